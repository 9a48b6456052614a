"""Meeting the spec: the stroke spacing that evens out the film, and the gun speed that puts it on target.

On a flat panel painted by long parallel strokes at spacing s, each perpendicular to the gun at the pattern's
standoff, the film across the strokes is the 1-D superposition of the pattern's across-stroke profile p(y)
(``SprayPattern.profile``)::

    T(y) = Q / v * sum_k p(y - k s)

It is periodic in y with period s, and its mean over a period is exactly Q / (v s) (the profile integrates to
1). So the *speed* that puts the mean on the target T* is v = Q / (s T*), whatever the spacing, and the
*spacing* only decides the ripple: the coefficient of variation (std / mean over a period) of
sum_k p(y - k s). The ripple is not monotonic in s: it has local minima where the overlapping flanks of
neighbouring strokes add up to a nearly flat film. :func:`choose_spacing` scans s from 0.2 R to 2 R, refines
every local minimum of the ripple, and picks the *widest* spacing whose ripple is within ``cv_tolerance``
(wider strokes: fewer passes, less time); if none is, the spacing of least ripple.

Seed 000 instead fixes the overlap of the spray circles at 0.4 (spacing 49.19 mm for r = 50 mm), whatever
the pattern's shape: :func:`ripple_cv` at that spacing shows what that costs in uniformity.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from sprayplan.coating.patterns import SprayPattern
from sprayplan.coating.process import Process
from sprayplan.errors import ConfigError
from sprayplan.surface.coverage import overlap_ratio

#: samples per period when measuring the ripple
_PERIOD_SAMPLES = 256


@dataclass(frozen=True)
class SpacingChoice:
    """A stroke spacing and gun speed for a pattern and a film target.

    Attributes
    ----------
    spacing_mm : float
        Distance between adjacent strokes (at the pattern's standoff, or the given one).
    speed_mm_s : float
        Gun speed that puts the mean film on the target at that spacing.
    cv : float
        Ripple of the film across parallel strokes on a flat panel: std / mean over a period.
    overlap : float
        Seed 000's overlap ratio of two circles of the pattern's radius at this spacing (eq. 6).
    target_um : float
    scan_spacing_mm : (k,) float
        The spacings scanned.
    scan_cv : (k,) float
        Their ripple.
    """

    spacing_mm: float
    speed_mm_s: float
    cv: float
    overlap: float
    target_um: float
    scan_spacing_mm: np.ndarray
    scan_cv: np.ndarray


def film_across(pattern: SprayPattern, spacing_mm: float, y_mm) -> np.ndarray:
    """sum_k p(y - k s): the film across infinitely many parallel strokes per unit Q / v, 1/mm.

    Parameters
    ----------
    pattern : SprayPattern
    spacing_mm : float
    y_mm : (n,) float
        Offsets across the strokes.
    """
    y = np.atleast_1d(np.asarray(y_mm, float))
    reach = math.ceil(pattern.support_radius_mm / spacing_mm) + 1
    k = np.arange(-reach, reach + 1)
    return pattern.profile((y[:, None] - k[None, :] * spacing_mm).ravel()).reshape(len(y), -1).sum(axis=1)


def ripple_cv(pattern: SprayPattern, spacing_mm: float) -> float:
    """std / mean of the film across parallel strokes at ``spacing_mm`` on a flat panel."""
    if not spacing_mm > 0:
        raise ConfigError(f"spacing must be positive, got {spacing_mm}")
    y = (np.arange(_PERIOD_SAMPLES) + 0.5) / _PERIOD_SAMPLES * spacing_mm
    film = film_across(pattern, spacing_mm, y)
    mean = film.mean()
    return float(film.std() / mean) if mean > 0 else float("inf")


def speed_for_target(volume_rate_mm3_s: float, spacing_mm: float, target_um: float) -> float:
    """Gun speed (mm/s) that gives the mean film ``target_um`` at a spacing: v = Q / (s T)."""
    if not (spacing_mm > 0 and target_um > 0):
        raise ConfigError("spacing and target must be positive")
    return volume_rate_mm3_s / (spacing_mm * target_um / 1000.0)


def choose_spacing(
    pattern: SprayPattern,
    *,
    cv_tolerance: float = 0.01,
    standoff_mm: float | None = None,
    min_spacing_mm: float | None = None,
    max_spacing_mm: float | None = None,
) -> tuple[float, float, np.ndarray, np.ndarray]:
    """The widest spacing at a local minimum of the ripple within ``cv_tolerance`` (see the module notes).

    Parameters
    ----------
    pattern : SprayPattern
    cv_tolerance : float
        Largest acceptable ripple (std / mean).
    standoff_mm : float, optional
        Painting standoff, when it differs from the pattern's: the pattern is scaled to it first.
    min_spacing_mm, max_spacing_mm : float, optional
        Scan range; default 0.2 R and 2 R (R at the standoff).

    Returns
    -------
    spacing_mm : float
    cv : float
    scan_spacing_mm, scan_cv : (k,) float
    """
    if standoff_mm is not None:
        pattern = pattern.scaled(standoff_mm / pattern.standoff_mm)
    r = pattern.support_radius_mm
    lo = 0.2 * r if min_spacing_mm is None else float(min_spacing_mm)
    hi = 2.0 * r if max_spacing_mm is None else float(max_spacing_mm)
    if not 0 < lo < hi:
        raise ConfigError(f"need 0 < min_spacing_mm < max_spacing_mm, got {lo}, {hi}")
    grid = np.linspace(lo, hi, 361)
    cvs = np.array([ripple_cv(pattern, s) for s in grid])
    minima = [i for i in range(1, len(grid) - 1) if cvs[i] <= cvs[i - 1] and cvs[i] <= cvs[i + 1]]
    candidates = []
    for i in minima:
        res = minimize_scalar(
            lambda s: ripple_cv(pattern, s),
            bounds=(grid[i - 1], grid[i + 1]),
            method="bounded",
            options={"xatol": 1e-3 * r},
        )
        s_best, cv_best = (float(res.x), float(res.fun)) if res.fun <= cvs[i] else (float(grid[i]), float(cvs[i]))
        candidates.append((s_best, cv_best))
    candidates.append((float(grid[0]), float(cvs[0])))
    good = [c for c in candidates if c[1] <= cv_tolerance]
    spacing, cv = max(good) if good else min(candidates, key=lambda c: c[1])
    return spacing, cv, grid, cvs


def choose_spacing_and_speed(
    process: Process,
    target_um: float = 50.0,
    *,
    cv_tolerance: float = 0.01,
    standoff_mm: float | None = None,
) -> SpacingChoice:
    """Spacing (least ripple, widest within tolerance) and the speed that puts the mean film on target.

    Parameters
    ----------
    process : Process
        Its pattern and dry volume rate (flow x solids x efficiency); its own speed is not used.
    target_um : float
    cv_tolerance : float
    standoff_mm : float, optional
        Painting standoff if not the pattern's.

    Returns
    -------
    SpacingChoice
    """
    spacing, cv, grid, cvs = choose_spacing(process.pattern, cv_tolerance=cv_tolerance, standoff_mm=standoff_mm)
    speed = speed_for_target(process.volume_rate_mm3_s, spacing, target_um)
    radius = process.pattern.support_radius_mm * (
        1.0 if standoff_mm is None else standoff_mm / process.pattern.standoff_mm
    )
    return SpacingChoice(spacing, speed, cv, float(overlap_ratio(spacing, radius)), float(target_um), grid, cvs)
