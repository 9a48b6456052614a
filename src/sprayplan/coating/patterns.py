"""Deposition models: how a gun spreads paint over a plane perpendicular to its axis at its standoff.

A pattern is a *density* over the pattern plane: ``density(x, y)`` (1/mm^2) integrates to 1 over the plane, so
the film growth rate on that plane is ``volume_rate * density(x, y)`` (mm/s) for a dry-film volume rate
``volume_rate`` = flow x solids fraction x transfer efficiency (mm^3/s). Every model is therefore normalised so
that the integral of the film growth rate equals the dry-film volume rate.

Pattern-plane coordinates: the plane lies ``standoff_mm`` from the gun tip along the gun axis; ``x`` runs
along the gun's travel and ``y`` across it (``y = axis x x``), both in mm from the axis.

Models (f_max is fixed by the normalisation):

``flat``
    uniform disc of radius R: f = f_max for r < R.
``parabolic``
    f = f_max (1 - r^2/R^2), the beta model with beta = 2.
``beta``
    f = f_max (1 - r^2/R^2)^(beta - 1), integral pi R^2 f_max / beta.
``gaussian``
    f = f_max exp(-r^2 / (2 sigma^2)), truncated at r = R (R = 3 sigma catches 98.9 % of an untruncated one);
    the truncated density is normalised on its disc, integral 2 pi sigma^2 (1 - exp(-R^2 / 2 sigma^2)) f_max.
``double_beta``
    the elliptical double-beta model of Balkan & Arikan (Mech. Res. Commun. 26(5), 1999) for guns whose pattern
    is not round: with semi-axes a (along x) and b (across, y),
    f = f_max (1 - x^2/a^2)^(beta1 - 1) (1 - y^2 / (b^2 (1 - x^2/a^2)))^(beta2 - 1) inside the ellipse;
    integral a b B(1/2, beta2) B(1/2, beta1 + 1/2) f_max, B the Euler beta function (integrate over y at a
    fixed x, chord half-width b sqrt(1 - x^2/a^2), then over x).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.integrate import trapezoid
from scipy.special import beta as beta_fn
from scipy.special import erf, roots_jacobi

from sprayplan.errors import ConfigError

KINDS = ("flat", "parabolic", "beta", "gaussian", "double_beta")

#: Gauss-Jacobi nodes used for the across-stroke profile of the double-beta model.
_PROFILE_NODES = 96


@dataclass(frozen=True)
class SprayPattern:
    """A spray pattern on the plane at ``standoff_mm`` in front of the gun, perpendicular to its axis.

    Attributes
    ----------
    kind : {"flat", "parabolic", "beta", "gaussian", "double_beta"}
    radius_mm : float
        Support radius R (flat, parabolic, beta; truncation radius of the Gaussian). For ``double_beta`` it is
        set to max(a, b).
    standoff_mm : float
        Distance h from the gun tip to the pattern plane along the axis.
    beta : float
        Exponent of the ``beta`` model (> 0); forced to 1 for ``flat`` and 2 for ``parabolic``.
    sigma_mm : float or None
        Standard deviation of the ``gaussian`` model; None: R / 3.
    a_mm, b_mm : float or None
        Semi-axes of the ``double_beta`` ellipse along the travel (x) and across it (y).
    beta1, beta2 : float
        Exponents of the ``double_beta`` model along x and across.
    name : str
    """

    kind: str = "beta"
    radius_mm: float = 50.0
    standoff_mm: float = 113.0
    beta: float = 2.0
    sigma_mm: float | None = None
    a_mm: float | None = None
    b_mm: float | None = None
    beta1: float = 2.0
    beta2: float = 2.0
    name: str = ""

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ConfigError(f"pattern kind must be one of {', '.join(KINDS)}, got {self.kind!r}")
        if self.kind == "flat":
            object.__setattr__(self, "beta", 1.0)
        elif self.kind == "parabolic":
            object.__setattr__(self, "beta", 2.0)
        elif self.kind == "gaussian" and self.sigma_mm is None:
            object.__setattr__(self, "sigma_mm", self.radius_mm / 3.0)
        elif self.kind == "double_beta":
            if self.a_mm is None or self.b_mm is None:
                raise ConfigError("a double_beta pattern needs a_mm and b_mm")
            object.__setattr__(self, "radius_mm", float(max(self.a_mm, self.b_mm)))
        for key in ("radius_mm", "standoff_mm", "beta", "beta1", "beta2", "sigma_mm", "a_mm", "b_mm"):
            value = getattr(self, key)
            if value is not None and not (math.isfinite(value) and value > 0):
                raise ConfigError(f"pattern {key} must be a positive number, got {value}")
            if value is not None:
                object.__setattr__(self, key, float(value))

    # -------------------------------------------------------------------------------------------- shape

    @property
    def support_radius_mm(self) -> float:
        """Radius of the disc outside which the density is 0, on the pattern plane, mm."""
        return self.radius_mm

    @property
    def peak_integral(self) -> float:
        """Integral over the plane of the unnormalised shape (f_max = 1), mm^2."""
        r = self.radius_mm
        if self.kind in ("flat", "parabolic", "beta"):
            return math.pi * r * r / self.beta
        if self.kind == "gaussian":
            s = self.sigma_mm
            return 2.0 * math.pi * s * s * (1.0 - math.exp(-r * r / (2.0 * s * s)))
        return self.a_mm * self.b_mm * beta_fn(0.5, self.beta2) * beta_fn(0.5, self.beta1 + 0.5)

    def shape(self, x, y) -> np.ndarray:
        """Unnormalised shape, 1 at its peak.

        Parameters
        ----------
        x, y : (n,) float, mm
            Pattern-plane coordinates along and across the travel.

        Returns
        -------
        (n,) float
        """
        x, y = _floats(x), _floats(y)
        if self.kind == "double_beta":
            s = 1.0 - (x / self.a_mm) ** 2
            inside = s > 0
            s_safe = np.where(inside, s, 1.0)
            t = 1.0 - (y / self.b_mm) ** 2 / s_safe
            inside &= t > 0
            out = np.where(
                inside, _pow(s_safe, self.beta1 - 1.0) * _pow(np.where(inside, t, 1.0), self.beta2 - 1.0), 0.0
            )
            return out
        r2 = (x * x + y * y) / (self.radius_mm * self.radius_mm)
        if self.kind == "gaussian":
            g = np.exp(-(x * x + y * y) / (2.0 * self.sigma_mm**2))
            return np.where(r2 < 1.0, g, 0.0)
        inside = r2 < 1.0
        return np.where(inside, _pow(np.where(inside, 1.0 - r2, 1.0), self.beta - 1.0), 0.0)

    def radial_density(self, r2) -> np.ndarray:
        """Normalised density (1/mm^2) of a round pattern (all kinds but ``double_beta``) at squared radii r^2
        (mm^2); keeps float32 input as float32."""
        r2 = _floats(r2)
        if self.kind == "double_beta":
            raise ConfigError("a double_beta pattern is not round: use density(x, y)")
        u = r2 * (1.0 / (self.radius_mm * self.radius_mm))
        inside = u < 1.0
        if self.kind == "gaussian":
            shape = np.where(inside, np.exp(r2 * (-0.5 / self.sigma_mm**2)), 0.0)
        else:
            shape = np.where(inside, _pow(np.where(inside, 1.0 - u, 1.0), self.beta - 1.0), 0.0)
        return shape * (1.0 / self.peak_integral)

    def density(self, x, y) -> np.ndarray:
        """Normalised density (integral 1 over the plane), 1/mm^2, at pattern-plane points (mm)."""
        return self.shape(x, y) / self.peak_integral

    def profile(self, y) -> np.ndarray:
        """Across-stroke profile: the density integrated along the travel, int density(x, y) dx (1/mm).

        A straight stroke at speed v with dry volume rate Q leaves a film ``Q / v * profile(y)`` (mm) at the
        across-stroke offset y on the pattern plane.

        Parameters
        ----------
        y : (n,) float, mm

        Returns
        -------
        (n,) float, 1/mm
        """
        y = np.atleast_1d(np.asarray(y, dtype=float))
        r = self.radius_mm
        if self.kind in ("flat", "parabolic", "beta"):
            c2 = np.maximum(r * r - y * y, 0.0)
            b = self.beta
            out = beta_fn(0.5, b) * c2 ** (b - 0.5) / r ** (2.0 * b - 2.0)
            return out / self.peak_integral
        if self.kind == "gaussian":
            s = self.sigma_mm
            c = np.sqrt(np.maximum(r * r - y * y, 0.0))
            out = np.exp(-y * y / (2.0 * s * s)) * math.sqrt(2.0 * math.pi) * s * erf(c / (math.sqrt(2.0) * s))
            return out / self.peak_integral
        return self._double_beta_profile(y)

    def _double_beta_profile(self, y: np.ndarray) -> np.ndarray:
        # chord half-length along x at offset y: c = a sqrt(1 - y^2/b^2); with x = c t the integrand is
        # s^(beta1 - beta2) (c/a)^(2 beta2 - 2) (1 - t^2)^(beta2 - 1), s = 1 - (c t / a)^2: Gauss-Jacobi in t.
        a, b = self.a_mm, self.b_mm
        nodes, weights = roots_jacobi(_PROFILE_NODES, self.beta2 - 1.0, self.beta2 - 1.0)
        q = np.clip(1.0 - (y / b) ** 2, 0.0, None)
        c = a * np.sqrt(q)
        s = 1.0 - (c[:, None] / a * nodes[None, :]) ** 2
        integral = (weights[None, :] * np.maximum(s, 1e-300) ** (self.beta1 - self.beta2)).sum(axis=1)
        out = c * q ** (self.beta2 - 1.0) * integral
        return np.where(q > 0, out, 0.0) / self.peak_integral

    def variance_across_mm2(self) -> float:
        """Variance of the density across the travel (second moment of the profile), mm^2."""
        y = np.linspace(-self.radius_mm, self.radius_mm, 2001)
        p = self.profile(y)
        return float(trapezoid(p * y * y, y) / trapezoid(p, y))

    def scaled(self, factor: float) -> SprayPattern:
        """The same pattern with every length multiplied by ``factor`` (a gun moved to factor x its standoff)."""
        kw = {"radius_mm": self.radius_mm * factor, "standoff_mm": self.standoff_mm * factor}
        for key in ("sigma_mm", "a_mm", "b_mm"):
            if getattr(self, key) is not None:
                kw[key] = getattr(self, key) * factor
        return replace(self, **kw)

    def to_dict(self) -> dict:
        """The parameters that define the pattern, as a TOML-ready table (None values left out)."""
        keys = {
            "flat": ("radius_mm",),
            "parabolic": ("radius_mm",),
            "beta": ("radius_mm", "beta"),
            "gaussian": ("radius_mm", "sigma_mm"),
            "double_beta": ("a_mm", "b_mm", "beta1", "beta2"),
        }[self.kind]
        out = {"kind": self.kind, "standoff_mm": self.standoff_mm}
        out.update({k: float(getattr(self, k)) for k in keys})
        if self.name:
            out["name"] = self.name
        return out


def _floats(values) -> np.ndarray:
    """An array of floats, keeping float32 input as float32 (the thickness kernel works in float32)."""
    out = np.asarray(values)
    return out if out.dtype.kind == "f" else out.astype(float)


def _pow(base: np.ndarray, exponent: float) -> np.ndarray:
    """``base ** exponent`` with the common integer exponents done by multiplication (faster than pow)."""
    if exponent == 0.0:
        return np.ones_like(base)
    if exponent == 1.0:
        return base
    if exponent == 2.0:
        return base * base
    return np.power(base, exponent)


def pattern_from_dict(table: dict) -> SprayPattern:
    """Build a :class:`SprayPattern` from a TOML table, rejecting unknown keys.

    Parameters
    ----------
    table : dict
        Keys as the attribute names of :class:`SprayPattern`.
    """
    names = set(SprayPattern.__dataclass_fields__)
    unknown = sorted(set(table) - names)
    if unknown:
        raise ConfigError(f"unknown pattern key(s): {', '.join(unknown)}; known: {', '.join(sorted(names))}")
    return SprayPattern(**table)
