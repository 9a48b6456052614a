"""Fitting a spray pattern to measurements: a test-panel stroke, or a simulated deposition.

A test panel: one straight stroke at a known speed v over a flat panel, perpendicular to the gun at the
pattern's standoff, leaves the film T(y) = Q / v * p(y - y0) across the stroke (p = ``SprayPattern.profile``).
:func:`fit_stroke_profile` finds Q, y0 and the pattern's shape parameters by least squares on the measured
thickness; with the flow and the solids fraction known, Q gives the transfer efficiency.

A deposition map (for instance the landing density of the droplet model, ``droplet.landing_density``):
:func:`fit_density` fits the normalised density of a pattern to it.

Shape parameters fitted per model: flat / parabolic: R; beta: R, beta; gaussian: R, sigma (R >= 2.5 sigma
kept free, so a truncated Gaussian can be fitted); double_beta: from a single stroke b and beta2 only (the
across profile does not depend on a, and barely on beta1: doubling beta1 from 2.2 changes it by 0.6 %, so
both stay as given); from a 2-D map a, b, beta1, beta2.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np
from scipy.integrate import trapezoid
from scipy.optimize import least_squares

from sprayplan.coating.patterns import SprayPattern
from sprayplan.errors import ConfigError

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class PatternFit:
    """A fitted pattern.

    Attributes
    ----------
    pattern : SprayPattern
    volume_rate_mm3_s : float
        Dry-film volume rate Q (stroke fits; NaN for density fits).
    centre_mm : float or (2,) float
        Offset of the stroke (y0) or of the pattern's centre (x0, y0) in the data's frame.
    rms : float
        Root mean square residual (um for stroke fits, 1/mm^2 for density fits).
    relative_rms : float
        ``rms`` over the data's peak.
    transfer_efficiency : float or None
        Q / (flow x solids), when the flow and solids were given.
    """

    pattern: SprayPattern
    volume_rate_mm3_s: float
    centre_mm: float | np.ndarray
    rms: float
    relative_rms: float
    transfer_efficiency: float | None = None


_SHAPE_KEYS = {
    "flat": ("radius_mm",),
    "parabolic": ("radius_mm",),
    "beta": ("radius_mm", "beta"),
    "gaussian": ("radius_mm", "sigma_mm"),
    "double_beta": ("b_mm", "beta2"),
}


def _initial_shape(kind: str, width: float, a_mm: float | None) -> dict:
    """Starting shape parameters from the across-stroke standard deviation ``width`` (mm)."""
    if kind in ("flat", "parabolic", "beta"):
        beta = {"flat": 1.0, "parabolic": 2.0, "beta": 2.0}[kind]
        return {"radius_mm": width * np.sqrt(2.0 * (beta + 1.0)), "beta": beta}
    if kind == "gaussian":
        return {"radius_mm": 3.5 * width, "sigma_mm": width}
    return {"a_mm": a_mm if a_mm is not None else 2.5 * width, "b_mm": 2.5 * width, "beta1": 2.0, "beta2": 2.0}


def _pattern(kind: str, standoff: float, base: dict, keys, values) -> SprayPattern:
    kw = dict(base)
    kw.update({k: float(v) for k, v in zip(keys, values)})
    kw = {k: v for k, v in kw.items() if k in SprayPattern.__dataclass_fields__}
    return SprayPattern(kind=kind, standoff_mm=standoff, **kw)


def fit_stroke_profile(
    offset_mm,
    thickness_um,
    speed_mm_s: float,
    kind: str = "beta",
    *,
    standoff_mm: float = 113.0,
    a_mm: float | None = None,
    beta1: float = 2.0,
    flow_ml_min: float | None = None,
    solids_fraction: float | None = None,
) -> PatternFit:
    """Fit a pattern to the film measured across one straight stroke on a flat test panel.

    Parameters
    ----------
    offset_mm : (n,) float
        Measuring positions across the stroke (any origin).
    thickness_um : (n,) float
        Dry film thickness there.
    speed_mm_s : float
        The gun's speed during the stroke.
    kind : str
        Model to fit (see :mod:`sprayplan.coating.patterns`).
    standoff_mm : float
        Standoff of the test stroke: the fitted pattern's plane.
    a_mm, beta1 : float, optional
        ``double_beta`` only: the semi-axis and exponent along the travel (not identifiable from one stroke).
    flow_ml_min, solids_fraction : float, optional
        When both are given, the transfer efficiency is reported.

    Returns
    -------
    PatternFit
    """
    y = np.asarray(offset_mm, float).reshape(-1)
    t = np.asarray(thickness_um, float).reshape(-1)
    if len(y) != len(t) or len(y) < 4:
        raise ConfigError("need at least 4 measurements, as many offsets as thicknesses")
    if kind not in _SHAPE_KEYS:
        raise ConfigError(f"cannot fit kind {kind!r}; known: {', '.join(_SHAPE_KEYS)}")
    order = np.argsort(y)
    y, t = y[order], t[order]
    area = float(trapezoid(t, y))
    if not area > 0:
        raise ConfigError("the measured film has no positive area")
    centre = float(trapezoid(t * y, y) / area)
    var = float(trapezoid(t * (y - centre) ** 2, y) / area)
    width = float(np.sqrt(max(var, 1e-6)))
    base = _initial_shape(kind, width, a_mm)
    base["beta1"] = float(beta1)
    keys = _SHAPE_KEYS[kind]
    q0 = area / 1000.0 * speed_mm_s
    x0 = np.array([np.log(q0), centre, *[np.log(base[k]) for k in keys]])

    def model(params):
        pattern = _pattern(kind, standoff_mm, base, keys, np.exp(params[2:]))
        return np.exp(params[0]) / speed_mm_s * pattern.profile(y - params[1]) * 1000.0

    peak = float(t.max())

    def residual(params):  # scaled to the peak, so that the solver's tolerances apply
        try:
            return (model(params) - t) / peak
        except ConfigError:
            return np.full(len(t), 1e6)

    res = least_squares(residual, x0, method="trf", x_scale="jac")
    pattern = _pattern(kind, standoff_mm, base, keys, np.exp(res.x[2:]))
    q = float(np.exp(res.x[0]))
    rms = float(np.sqrt(np.mean(res.fun**2))) * peak
    eff = None
    if flow_ml_min and solids_fraction:
        eff = q / (flow_ml_min * 1000.0 / 60.0 * solids_fraction)
    log.debug("fitted %s: Q %.4g mm^3/s, rms %.3g um", kind, q, rms)
    return PatternFit(pattern, q, float(res.x[1]), rms, rms / peak, eff)


def fit_density(
    x_mm, y_mm, density, kind: str = "beta", *, standoff_mm: float = 113.0, centred: bool = True
) -> PatternFit:
    """Fit a pattern's normalised density (1/mm^2) to a deposition map on the pattern plane.

    Parameters
    ----------
    x_mm, y_mm : (n,) float
        Cell centres (x along the travel, y across).
    density : (n,) float
        Share of the deposited paint per area, 1/mm^2 (integral about 1).
    kind : str
    standoff_mm : float
        The plane's distance from the gun.
    centred : bool
        Keep the pattern on the origin; False: fit its centre too.

    Returns
    -------
    PatternFit
        ``volume_rate_mm3_s`` is NaN (the map carries no rate).
    """
    x = np.asarray(x_mm, float).reshape(-1)
    y = np.asarray(y_mm, float).reshape(-1)
    d = np.asarray(density, float).reshape(-1)
    if kind not in _SHAPE_KEYS:
        raise ConfigError(f"cannot fit kind {kind!r}; known: {', '.join(_SHAPE_KEYS)}")
    total = d.sum()
    if not total > 0:
        raise ConfigError("the deposition map is empty")
    cx, cy = (x * d).sum() / total, (y * d).sum() / total
    var_y = max((d * (y - cy) ** 2).sum() / total, 1e-6)
    var_x = max((d * (x - cx) ** 2).sum() / total, 1e-6)
    base = _initial_shape(kind, float(np.sqrt(var_y)), float(np.sqrt(var_x)) * 2.5)
    keys = _SHAPE_KEYS[kind] if kind != "double_beta" else ("a_mm", "b_mm", "beta1", "beta2")
    start = [np.log(base[k]) for k in keys]
    x0 = np.array(start if centred else [cx, cy, *start])

    peak = float(d.max())

    def residual(params):  # scaled to the peak, so that the solver's tolerances apply
        off = (0.0, 0.0) if centred else (params[0], params[1])
        shape = params if centred else params[2:]
        try:
            pattern = _pattern(kind, standoff_mm, base, keys, np.exp(shape))
        except ConfigError:
            return np.full(len(d), 1e3)
        return (pattern.density(x - off[0], y - off[1]) - d) / peak

    res = least_squares(residual, x0, method="trf", x_scale="jac")
    shape = res.x if centred else res.x[2:]
    pattern = _pattern(kind, standoff_mm, base, keys, np.exp(shape))
    centre = np.zeros(2) if centred else np.array(res.x[:2])
    rms = float(np.sqrt(np.mean(res.fun**2))) * peak
    return PatternFit(pattern, float("nan"), centre, rms, rms / peak)


def fit_droplets(
    result, kind: str = "beta", *, cell_mm: float | None = None, half_width_mm: float | None = None
) -> PatternFit:
    """Fit a pattern to the landing density of a droplet simulation (``droplet.simulate_droplets``).

    The pattern's plane is the droplet model's plate (standoff = the cup's height above it); the fit's
    ``transfer_efficiency`` is the simulation's.
    """
    from sprayplan.coating.droplet import landing_density

    x, y, d = landing_density(result, cell_mm, half_width_mm)
    fit = fit_density(x, y, d, kind, standoff_mm=result.config.standoff_mm)
    return replace(fit, transfer_efficiency=result.transfer_efficiency)


def named(fit: PatternFit, name: str) -> SprayPattern:
    """The fitted pattern with a name (for saving as a preset)."""
    return replace(fit.pattern, name=name)
