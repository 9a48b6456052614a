"""Overlap of two spray circles (seed 000, section 2.5, eq. 6) and the spacing that gives a wanted overlap.

Two spray circles of radius r whose centres are d apart (0 <= d <= 2r) overlap in a lens of area

    A(d) = 2 r^2 arccos(d / 2r) - d sqrt(r^2 - d^2 / 4)

The seed calls the ratio "coverage" p and prints eq. 6 as
``p = (4 r^2 arccos(d/2r) - d sqrt(r^2 - d^2/4)) / (2 pi r^2)``. That form is garbled: it gives p = 1 at d = 0
but is not a ratio of areas for any other d (its numerator is neither A nor 2A). The reading implemented here is

    p(d) = A(d) / (pi r^2) = (4 r^2 arccos(d/2r) - 2 d sqrt(r^2 - d^2/4)) / (2 pi r^2)

the lens area over the area of one circle: the printed fraction with the factor 2 of its second term restored.
It is 1 for coincident circles, 0 for touching ones, and decreases monotonically in between. For the seed's
r = 50 mm and p = 0.4 it gives d = 49.19 mm.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from sprayplan.errors import ConfigError


def overlap_ratio(distance_mm, radius_mm: float):
    """Overlap p of two circles of radius r at centre distance d: lens area over one circle's area.

    Parameters
    ----------
    distance_mm : float or (n,) float
        Centre distance d >= 0; beyond 2r the overlap is 0.
    radius_mm : float
        Spray circle radius r > 0.

    Returns
    -------
    float or (n,) float
        p in [0, 1].
    """
    if not radius_mm > 0:
        raise ConfigError(f"spray radius must be positive, got {radius_mm}")
    d = np.clip(np.asarray(distance_mm, dtype=float), 0.0, 2.0 * radius_mm)
    r = float(radius_mm)
    lens = 2.0 * r * r * np.arccos(d / (2.0 * r)) - d * np.sqrt(np.maximum(r * r - d * d / 4.0, 0.0))
    out = lens / (np.pi * r * r)
    return float(out) if out.ndim == 0 else out


def spacing_for_overlap(overlap: float, radius_mm: float) -> float:
    """The centre distance d at which two circles of radius r overlap by the ratio p (inverse of eq. 6).

    Parameters
    ----------
    overlap : float
        p in [0, 1).
    radius_mm : float

    Returns
    -------
    float
        d in (0, 2r], mm.
    """
    if not 0.0 <= overlap < 1.0:
        raise ConfigError(f"overlap must be in [0, 1), got {overlap}")
    if not radius_mm > 0:
        raise ConfigError(f"spray radius must be positive, got {radius_mm}")
    if overlap == 0.0:
        return 2.0 * radius_mm
    return float(brentq(lambda d: overlap_ratio(d, radius_mm) - overlap, 0.0, 2.0 * radius_mm, xtol=1e-12, rtol=1e-14))
