"""The bundled default part: a car-roof-like panel the size of seed 000's.

Seed 000 paints the part of a car roof above z = 1000 mm, whose envelope rectangle is 2635 x 1959 mm (its
section 6.2). The panel here is ``z = 1400 - 400 s^3`` over a superellipse radius
``s = (|x / 1317.5|^4 + |y / 979.5|^4)^(1/4)``: flat-topped at z = 1400 mm, curving down to z = 1000 mm exactly on
the 2635 x 1959 mm rounded rectangle, and continuing below it (to s = 1.15) so that the seed's region
``z > 1000`` has something to cut.
"""

from __future__ import annotations

import numpy as np

from sprayplan.types import Part

ROOF_HALF_LENGTH_MM = 2635.0 / 2.0
ROOF_HALF_WIDTH_MM = 1959.0 / 2.0
ROOF_TOP_MM = 1400.0
ROOF_DROP_MM = 400.0
DEMO_REGION = "z > 1000"


def roof_height(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """z (mm) of the demo roof over plan coordinates x, y (mm)."""
    s = (np.abs(x / ROOF_HALF_LENGTH_MM) ** 4 + np.abs(y / ROOF_HALF_WIDTH_MM) ** 4) ** 0.25
    return ROOF_TOP_MM - ROOF_DROP_MM * s**3


def car_roof(resolution_mm: float = 25.0, extent: float = 1.15) -> Part:
    """The demo roof as a triangle mesh, normals (winding) pointing up and out.

    Parameters
    ----------
    resolution_mm : float
        Grid step in plan.
    extent : float
        How far past the z = 1000 mm outline the panel goes, as a multiple of the half sizes.

    Returns
    -------
    Part
        Named ``demo:roof``.
    """
    xs = np.arange(-extent * ROOF_HALF_LENGTH_MM, extent * ROOF_HALF_LENGTH_MM + resolution_mm / 2, resolution_mm)
    ys = np.arange(-extent * ROOF_HALF_WIDTH_MM, extent * ROOF_HALF_WIDTH_MM + resolution_mm / 2, resolution_mm)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    vertices = np.stack([gx.ravel(), gy.ravel(), roof_height(gx, gy).ravel()], axis=1)
    nx, ny = len(xs), len(ys)
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), indexing="ij")
    a = (i * ny + j).ravel()
    b, c, d = a + ny, a + ny + 1, a + 1
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])  # counter-clockwise from above
    return Part(vertices, faces, None, "demo:roof")
