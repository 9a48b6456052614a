"""The solid bodies of the nine-axis cell, as data: the arm's links, the gun, the gantry's carriage and column.

Every body of the robot is a capsule (a segment swept by a sphere), given in one frame of the D-H chain:
frame 0 is the arm's base (``base2world``), frame ``i`` the frame after joint ``i`` (standard D-H, seed 000's
eq. 10; frame 6 is the flange). A capsule's two end points are in that frame's coordinates, mm.

Link sizes of the UR arms (:data:`LINK_BODIES`)
-----------------------------------------------
The standard D-H table puts the shoulder, elbow and wrist axes in one plane and gathers the arm's sideways
offsets into ``d4``; the real upper arm and forearm lie beside that plane, along the joint axes. The capsules
follow the real arm: the upper arm runs ``shoulder_offset`` along the shoulder/elbow axis from the D-H plane,
the forearm ``shoulder_offset - elbow_offset``, and the wrist-1 housing closes the rest to ``d4``
(the three add up to ``d4``: 135.85 - 119.7 + 93.0 = 109.15 mm on the UR5).

Where the numbers come from:

- the D-H values are the robot model's own (``robots.model.PRESETS``: Universal Robots' published tables);
- the sideways offsets are Universal Robots' published link geometry as carried by the ROS-Industrial
  ``ur_description`` models: UR5 shoulder offset 135.85 mm, elbow offset 119.7 mm; UR5e 138.0 mm and 131.0 mm;
- the base radius is the published footprint, diameter 149 mm on the UR5 and the UR5e (radius 75 mm);
- the other radii are **envelope estimates, not published figures**, rounded up: the joint housings (the
  shoulder 60 mm, the elbow 50 mm, the wrists 40 mm) are their own capsules across their joint axes, and the
  tubes between them are slimmer (upper arm 45 mm, forearm 38 mm); the housings at a tube's ends cover its
  flanges. The tool flange (diameter 63 mm) lies inside the wrist-3 capsule. Replace them from the maker's
  dimension drawing when one is at hand.

The ``ur5-seed`` table (seed 000's rounded values, a2 and a3 positive) reuses the UR5's sizes: its link
lengths are ``|a2|, |a3|``, which is what the capsules use.

The gun (:func:`gun_capsule`)
-----------------------------
A capsule from the flange centre toward the nozzle (the origin of ``gun2flange``, the TCP), of a radius set by
:class:`~sprayplan.collision.settings.CollisionConfig`. It stops where its cap touches the plane through the
nozzle normal to the gun's axis: nothing of the gun lies beyond the nozzle, so the spray cone in front of it is
free space. The cap then passes within ``r (1 / cos(beta) - 1)`` of the nozzle point (beta the angle between
the flange-to-nozzle line and the gun axis: 30 degrees for the WA-101, 4.6 mm at the default r = 30 mm).

The gantry (:class:`GantryBodies`)
----------------------------------
Seed 000 gives no gantry dimensions, only the side wall ``h0`` = 163 mm above the shoulder, i.e.
``h0 - d1`` = 74 mm above the arm's mounting plane. The carriage is a box of that height right above the
mounting plane, the vertical column a box above the carriage; both move with the platform (tx, ty, tz). Their
widths and the column's length are settings of :class:`GantryBodies`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sprayplan.errors import ConfigError
from sprayplan.robots.gantry import Gun
from sprayplan.robots.model import RobotModel


@dataclass(frozen=True)
class CapsuleBody:
    """A capsule fixed in one frame of the D-H chain.

    Attributes
    ----------
    name : str
    frame : int
        0 the arm's base, ``i`` the frame after joint ``i`` (6: the flange).
    p0, p1 : (3,) float, mm
        The segment's ends in that frame.
    radius_mm : float
    """

    name: str
    frame: int
    p0: tuple
    p1: tuple
    radius_mm: float

    @property
    def length_mm(self) -> float:
        """The segment's length (without the caps)."""
        return float(np.linalg.norm(np.subtract(self.p1, self.p0)))


@dataclass(frozen=True)
class URLinkSizes:
    """The link sizes of a UR arm that the D-H table does not hold (see the module docstring for sources).

    Attributes
    ----------
    shoulder_offset_mm, elbow_offset_mm : float
        The upper arm's distance from the D-H plane along the shoulder axis; the forearm's, back toward it.
    base_radius_mm, shoulder_radius_mm, upper_arm_radius_mm, elbow_radius_mm, forearm_radius_mm, wrist_radius_mm
        Capsule radii, mm.
    """

    shoulder_offset_mm: float
    elbow_offset_mm: float
    base_radius_mm: float = 75.0
    shoulder_radius_mm: float = 60.0
    upper_arm_radius_mm: float = 45.0
    elbow_radius_mm: float = 50.0
    forearm_radius_mm: float = 38.0
    wrist_radius_mm: float = 40.0


#: Link sizes per UR preset of ``robots.model`` (sources in the module docstring).
UR_LINK_SIZES = {
    "ur5": URLinkSizes(shoulder_offset_mm=135.85, elbow_offset_mm=119.7),
    "ur5-seed": URLinkSizes(shoulder_offset_mm=135.85, elbow_offset_mm=119.7),
    "ur5e": URLinkSizes(shoulder_offset_mm=138.0, elbow_offset_mm=131.0),
}

#: The bodies of the arm named in reports, base to flange.
LINK_NAMES = ("base", "shoulder", "upper_arm", "elbow", "forearm", "wrist_1", "wrist_2", "wrist_3")


def link_bodies(model: RobotModel) -> tuple[CapsuleBody, ...]:
    """The capsules of a UR arm along its D-H chain (the names of :data:`LINK_NAMES`).

    Raises
    ------
    ConfigError
        A robot without link sizes in :data:`UR_LINK_SIZES` (one line naming the robot).
    """
    if model.name not in UR_LINK_SIZES or model.dof != 6:
        known = ", ".join(UR_LINK_SIZES)
        raise ConfigError(f"robot {model.name!r} has no link sizes for collision checks: use one of {known}")
    s = UR_LINK_SIZES[model.name]
    d1, d4, d5, d6 = (float(model.d[i]) for i in (0, 3, 4, 5))
    z_up = s.shoulder_offset_mm  # the upper arm, along the shoulder (frame 1) and elbow (frame 2) axes
    z_fore = s.shoulder_offset_mm - s.elbow_offset_mm  # the forearm, along the elbow and wrist-1 axes
    # frame 2 has its origin on the elbow axis, its x axis along the arm (the shoulder at -a2 x2), and frame
    # 3 on the wrist-1 axis (the elbow at -a3 x3); both signs of a2, a3 (ur5, ur5-seed) put the far end at
    # -a_i along x_i
    sx2 = -float(model.a[1])
    sx3 = -float(model.a[2])
    wrist_3_end = max(d6 - s.wrist_radius_mm, 0.0)  # the cap ends at the flange face
    return (
        CapsuleBody("base", 0, (0.0, 0.0, 0.0), (0.0, 0.0, d1), s.base_radius_mm),
        CapsuleBody("shoulder", 1, (0.0, 0.0, 0.0), (0.0, 0.0, z_up), s.shoulder_radius_mm),
        CapsuleBody("upper_arm", 2, (sx2, 0.0, z_up), (0.0, 0.0, z_up), s.upper_arm_radius_mm),
        CapsuleBody("elbow", 2, (0.0, 0.0, z_up), (0.0, 0.0, z_fore), s.elbow_radius_mm),
        CapsuleBody("forearm", 3, (sx3, 0.0, z_fore), (0.0, 0.0, z_fore), s.forearm_radius_mm),
        CapsuleBody("wrist_1", 3, (0.0, 0.0, z_fore), (0.0, 0.0, d4), s.wrist_radius_mm),
        CapsuleBody("wrist_2", 4, (0.0, 0.0, 0.0), (0.0, 0.0, d5), s.wrist_radius_mm),
        CapsuleBody("wrist_3", 5, (0.0, 0.0, 0.0), (0.0, 0.0, wrist_3_end), s.wrist_radius_mm),
    )


def gun_capsule(gun: Gun, radius_mm: float) -> CapsuleBody:
    """The gun as a capsule in the flange frame (6), from the flange centre toward the nozzle, ending where
    its cap touches the nozzle's plane (see the module docstring).

    Raises
    ------
    ConfigError
        A gun whose nozzle is not in front of the flange by more than the radius (``collision.gun_radius_mm``).
    """
    gun2flange = np.asarray(gun.gun2flange, dtype=float)
    nozzle = gun2flange[:3, 3]
    axis = gun2flange[:3, 2]
    depth = float(nozzle @ axis)  # how far the nozzle's plane is in front of the flange centre, along the axis
    if depth <= radius_mm:
        raise ConfigError(
            f"collision.gun_radius_mm must be less than the gun {gun.name!r}'s depth ({depth:g} mm), got {radius_mm:g}"
        )
    end = nozzle * (1.0 - radius_mm / depth)  # on the flange-to-nozzle line, one radius behind the nozzle plane
    return CapsuleBody("gun", 6, (0.0, 0.0, 0.0), tuple(end.tolist()), float(radius_mm))


def gun_gap_to_nozzle_mm(gun: Gun, radius_mm: float) -> float:
    """How far the gun capsule's surface stays from the nozzle point, mm (0 for a gun along its own axis)."""
    nozzle = np.asarray(gun.gun2flange, dtype=float)[:3, 3]
    cos_beta = float(nozzle @ np.asarray(gun.gun2flange)[:3, 2]) / float(np.linalg.norm(nozzle))
    return radius_mm * (1.0 / cos_beta - 1.0)


@dataclass(frozen=True)
class GantryBodies:
    """The gantry's boxes above the arm's mounting plane (see the module docstring).

    Attributes
    ----------
    carriage_mm : (3,) float
        Width (x), depth (y) and height (z) of the carriage, right above the mounting plane.
    column_mm : (3,) float
        Width, depth and length of the vertical column, above the carriage.
    """

    carriage_mm: tuple = (300.0, 300.0, 74.0)
    column_mm: tuple = (200.0, 200.0, 1500.0)

    def __post_init__(self):
        for name in ("carriage_mm", "column_mm"):
            value = tuple(float(v) for v in getattr(self, name))
            if len(value) != 3 or not all(math.isfinite(v) and v > 0 for v in value):
                raise ConfigError(f"gantry {name} must be three positive sizes in mm, got {getattr(self, name)!r}")
            object.__setattr__(self, name, value)

    def centres_above_mount(self) -> dict[str, float]:
        """The boxes' centres' heights above the mounting plane, mm: ``{"carriage": ..., "column": ...}``."""
        carriage = self.carriage_mm[2]
        return {"carriage": carriage / 2.0, "column": carriage + self.column_mm[2] / 2.0}


def reach_radii_mm(model: RobotModel, bodies) -> np.ndarray:
    """(6,) float, mm: for each joint, a bound on how far any point of the bodies carried by it can be from
    its axis, whatever the joints: the chain's lengths from the joint on plus the largest capsule's reach.

    Each joint ``i`` turns the bodies in frames ``i..6`` about the axis through frame ``i - 1``; a point of a
    body in frame ``k`` is at most ``sum_{j=i..k} (|a_j| + |d_j|)`` from frame ``i - 1``'s origin plus its own
    distance from frame ``k``'s origin (the segment's far end and the radius).
    """
    lengths = np.abs(model.a) + np.abs(model.d)
    out = np.zeros(model.dof)
    for i in range(1, model.dof + 1):
        reach = 0.0
        for body in bodies:
            if body.frame < i:
                continue
            local = max(np.linalg.norm(body.p0), np.linalg.norm(body.p1)) + body.radius_mm
            reach = max(reach, float(lengths[i - 1 : body.frame].sum()) + local)
        out[i - 1] = reach
    return out
