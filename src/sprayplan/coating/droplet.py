r"""Electrostatic rotary-bell droplets (seed 003, section 4, eqs. 19-24), integrated by fixed-step Euler.

Units: this module works in SI (m, s, kg, C, V, Pa s) because its inputs are physical constants; positions
come in and go out in mm (``*_mm``), droplet sizes in um (``*_um``).

The model (seed 003, eq. 20, the simplified BBO equation; buoyancy, added mass and the Basset history term of
eq. 19 are dropped, as the seed does: a paint droplet is ~1000 times denser than air)::

    m dv/dt = F_D + F_E + F_g
    F_D = 3 pi mu_g D_p f (u - v)                                            (eq. 21, Stokes drag x f)
    f   = 1 + Re^(2/3) / 6          for Re < 1000                            (eq. 22)
        = 0.0183 Re                 for 1000 <= Re (< 3e5; used beyond it too)
    Re  = D_p |u - v| rho_g / mu_g                                           (eq. 22')
    u   = u_mean + u_turb                                                    (eq. 23)
    F_E = q E = -q grad(Phi),   F_g = m g                                    (eq. 24)

Which density in Re: the *air's*, rho_g. Re compares inertial and viscous forces in the air flowing around the
droplet, so it takes the density and viscosity of the continuous phase; the correlation 1 + Re^(2/3)/6
(Putnam's fit of the standard drag curve) is defined that way. The seed's extraction prints a bare rho next to
eq. 22 while its text calls rho the particle density; read with the droplet's density Re would be ~1000
times too large and the drag wrongly in the Newton regime.

Field model: the bell (cup radius r_b, voltage V) is a conducting sphere of radius r_b centred on the cup at
height H above the grounded part, a plane z = 0. By the method of images the plane is replaced by an opposite
charge at the mirror point, so the potential is exactly 0 on the plane::

    Phi(x) = k Q (1 / |x - c| - 1 / |x - c'|),   c = (0, 0, H),  c' = (0, 0, -H),  k = 1 / (4 pi eps0)
    E(x)   = k Q ((x - c) / |x - c|^3 - (x - c') / |x - c'|^3)

with Q chosen so that Phi = V at the sphere's lowest point: Q = V / (k (1/r_b - 1/(2H - r_b))). Inside the
sphere the field is taken at its surface. Space charge of the droplet cloud is neglected.

Air model (mean flow u_mean): the shaping air leaves a ring of holes just outside the cup's edge (radius
r_s) as an annular jet towards the part: axial speed U_c(s) exp(-(rho - r_s)^2 / w(s)^2) at the distance s
from the cup, with w(s) = w_0 + kappa s and U_c = U_0 sqrt(w_0 / w(s)) (the decay of a plane jet, which an
annulus much wider than thick resembles); U_0 is the shaping-air flow (SA2) over the holes' area. The jet
catches the droplets flung off the cup's edge and carries them to the part. Within one jet width delta of
the plate the jet turns into a stagnation-point flow: u_z = -U z / delta, u_rho = U rho / (2 delta)
(continuity), with U the jet's axial speed at z = delta. Turbulence (eq. 23): every eddy lifetime each
droplet draws an isotropic Gaussian fluctuation of standard deviation ``turbulence_intensity`` x |u_mean|
(seeded). Droplets leave the cup's edge tangentially at the cup's rim speed omega r_b.

Integration (eq. 24 by fixed-step Euler): x_(n+1) = x_n + dt v_n, v_(n+1) = v_n + dt a(x_n, v_n), until the
droplet crosses z = 0 (its landing point interpolated on the step), leaves the region, or the time runs out.
The explicit step is stable while dt is well below the droplet's relaxation time m / (3 pi mu D f), about
0.1-0.8 ms for 15-40 um droplets: the default 10 us is; a warning is logged when it is not.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from sprayplan.checks import check_work
from sprayplan.errors import ConfigError

log = logging.getLogger(__name__)

#: Droplets of one simulation (about 1 kB each while it runs), time steps (``max_time_s / dt_s``), and
#: droplets x steps (the default is 2000 x 20000 = 4e7, about a minute on two cores).
MAX_DROPLETS = 1_000_000
MAX_DROPLET_STEPS = 1_000_000
MAX_DROPLET_WORK = 1e9

EPS0 = 8.8541878128e-12
K_E = 1.0 / (4.0 * math.pi * EPS0)


@dataclass(frozen=True)
class DropletConfig:
    """A rotary-bell droplet simulation (defaults: seed 003 table 1 settings; the rest are assumptions).

    Attributes
    ----------
    count : int
        Droplets simulated.
    diameter_um : float
        Median droplet diameter.
    diameter_gsd : float
        Geometric standard deviation of the log-normal size distribution (1: all the same size).
    density_kg_m3 : float
        Paint density.
    charge_to_mass_c_kg : float
        Droplet charge per mass (3 % of the Rayleigh limit of a 25 um droplet).
    air_density_kg_m3, air_viscosity_pa_s : float
    standoff_mm : float
        H: cup to the grounded plane.
    voltage_kv : float
        Bell voltage ("HV", 60 kV).
    cup_radius_mm : float
    speed_krpm : float
        Bell speed ("AM", 40 krpm); 0: droplets start at rest.
    shaping_air_l_min : float
        Shaping air ("SA2", 180 L/min); 0: still air.
    outlet_area_mm2 : float
        Total area of the shaping-air holes: U_0 = flow / area (15 mm^2: 200 m/s at 180 L/min).
    ring_gap_mm : float
        The ring of shaping-air holes lies this far outside the cup's edge.
    jet_width_mm : float
        w_0, the annular jet's initial half width.
    jet_spread : float
        kappa, the jet's growth of width per distance.
    turbulence_intensity : float
    eddy_time_s : float
    gravity_m_s2 : tuple of float
        In the frame where the plate is z = 0 and the bell above it.
    dt_s : float
        Euler time step.
    max_time_s : float
    plate_radius_mm : float or None
        Landings farther than this from the axis miss the part; None: an infinite plate.
    seed : int
    """

    count: int = 2000
    diameter_um: float = 25.0
    diameter_gsd: float = 1.3
    density_kg_m3: float = 1200.0
    charge_to_mass_c_kg: float = 2e-3
    air_density_kg_m3: float = 1.2
    air_viscosity_pa_s: float = 1.8e-5
    standoff_mm: float = 200.0
    voltage_kv: float = 60.0
    cup_radius_mm: float = 32.5
    speed_krpm: float = 40.0
    shaping_air_l_min: float = 180.0
    outlet_area_mm2: float = 15.0
    ring_gap_mm: float = 2.0
    jet_width_mm: float = 10.0
    jet_spread: float = 0.1
    turbulence_intensity: float = 0.1
    eddy_time_s: float = 2e-3
    gravity_m_s2: tuple = (0.0, 0.0, -9.81)
    dt_s: float = 1e-5
    max_time_s: float = 0.2
    plate_radius_mm: float | None = None
    seed: int = 0

    @classmethod
    def from_bell(cls, bell, standoff_mm: float, **changes) -> DropletConfig:
        """Settings from a preset's :class:`~sprayplan.coating.process.BellSettings` (speed, SA2, HV, cup)."""
        kw = {
            "speed_krpm": bell.speed_krpm,
            "shaping_air_l_min": bell.shaping_air2_l_min,
            "voltage_kv": bell.voltage_kv,
            "cup_radius_mm": bell.cup_radius_mm,
            "standoff_mm": standoff_mm,
        }
        kw.update(changes)
        return cls(**kw)

    def __post_init__(self):
        positive = (
            "diameter_um",
            "diameter_gsd",
            "density_kg_m3",
            "air_viscosity_pa_s",
            "standoff_mm",
            "cup_radius_mm",
            "outlet_area_mm2",
            "jet_width_mm",
            "eddy_time_s",
            "dt_s",
            "max_time_s",
        )
        for key in positive:
            if not (math.isfinite(getattr(self, key)) and getattr(self, key) > 0):
                raise ConfigError(f"droplet {key} must be positive, got {getattr(self, key)}")
        if int(self.count) < 1 or self.diameter_gsd < 1 or self.cup_radius_mm >= self.standoff_mm:
            raise ConfigError("need count >= 1, diameter_gsd >= 1 and cup_radius_mm < standoff_mm")
        if self.count > MAX_DROPLETS:
            raise ConfigError(f"droplet count must be at most {MAX_DROPLETS}, got {self.count!r}")
        object.__setattr__(self, "gravity_m_s2", tuple(float(g) for g in self.gravity_m_s2))


@dataclass(frozen=True)
class DropletResult:
    """Where the droplets landed.

    Attributes
    ----------
    landing_mm : (n, 2) float
        x, y on the plate (NaN for droplets that did not land).
    landed : (n,) bool
        Landed on the plate (within ``plate_radius_mm``).
    diameter_um : (n,) float
    volume_mm3 : (n,) float
    flight_time_s : (n,) float
    transfer_efficiency : float
        Landed volume over sprayed volume.
    config : DropletConfig
    """

    landing_mm: np.ndarray
    landed: np.ndarray
    diameter_um: np.ndarray
    volume_mm3: np.ndarray
    flight_time_s: np.ndarray
    transfer_efficiency: float
    config: DropletConfig


def _check_steps(config: DropletConfig, count: int, steps: float) -> None:
    """Refuse, before integrating, more than ``MAX_DROPLET_STEPS`` time steps or ``MAX_DROPLET_WORK`` droplet
    steps (``count`` droplets over ``steps`` steps), naming the settings to change."""
    if steps > MAX_DROPLET_STEPS:
        raise ConfigError(
            f"droplet max_time_s / dt_s must be at most {MAX_DROPLET_STEPS} steps, got {steps:.3g}"
            f" (max_time_s {config.max_time_s:g}, dt_s {config.dt_s:g}): use dt_s >= {config.max_time_s / MAX_DROPLET_STEPS:.3g}"
        )
    check_work(
        count * steps,
        MAX_DROPLET_WORK,
        "droplet steps",
        "droplet count",
        int(count),
        f"{steps:.3g} time steps each",
        f"use count <= {max(1, int(MAX_DROPLET_WORK // steps))} or a larger dt_s",
    )


def drag_factor(reynolds: np.ndarray) -> np.ndarray:
    """f of seed 003 eq. 22: 1 + Re^(2/3)/6 below Re = 1000, 0.0183 Re above."""
    re = np.asarray(reynolds, float)
    return np.where(re < 1000.0, 1.0 + np.cbrt(re) ** 2 / 6.0, 0.0183 * re)


def bell_charge(voltage_v: float, cup_radius_m: float, standoff_m: float) -> float:
    """Charge Q (C) of the sphere-above-plane model whose potential is V at the sphere's lowest point."""
    return voltage_v / (K_E * (1.0 / cup_radius_m - 1.0 / (2.0 * standoff_m - cup_radius_m)))


def bell_field(points_m: np.ndarray, voltage_v: float, cup_radius_m: float, standoff_m: float) -> np.ndarray:
    """Electric field E = -grad Phi (V/m) of the image-charge bell model at points (m), (n, 3)."""
    q = bell_charge(voltage_v, cup_radius_m, standoff_m)
    p = np.atleast_2d(np.asarray(points_m, float))
    c = np.array([0.0, 0.0, standoff_m])
    rel = p - c
    dist = np.linalg.norm(rel, axis=1)
    rel = np.where((dist < cup_radius_m)[:, None], rel * (cup_radius_m / np.maximum(dist, 1e-12))[:, None], rel)
    dist = np.maximum(dist, cup_radius_m)
    img = p + c
    dimg = np.linalg.norm(img, axis=1)
    return K_E * q * (rel / dist[:, None] ** 3 - img / dimg[:, None] ** 3)


def bell_potential(points_m: np.ndarray, voltage_v: float, cup_radius_m: float, standoff_m: float) -> np.ndarray:
    """Potential Phi (V) of the image-charge bell model at points (m)."""
    q = bell_charge(voltage_v, cup_radius_m, standoff_m)
    p = np.atleast_2d(np.asarray(points_m, float))
    c = np.array([0.0, 0.0, standoff_m])
    d1 = np.maximum(np.linalg.norm(p - c, axis=1), cup_radius_m)
    return K_E * q * (1.0 / d1 - 1.0 / np.linalg.norm(p + c, axis=1))


def jet_air(points_m: np.ndarray, config: DropletConfig) -> np.ndarray:
    """Mean air velocity (m/s) of the shaping-air jet model at points (m), (n, 3)."""
    p = np.atleast_2d(np.asarray(points_m, float))
    u0 = config.shaping_air_l_min / 60000.0 / (config.outlet_area_mm2 * 1e-6)
    if u0 == 0.0:
        return np.zeros_like(p)
    h = config.standoff_mm / 1000.0
    ring = (config.cup_radius_mm + config.ring_gap_mm) / 1000.0
    w0 = config.jet_width_mm / 1000.0
    rho = np.hypot(p[:, 0], p[:, 1])
    delta = w0 + config.jet_spread * h
    z = np.clip(p[:, 2], 0.0, None)
    s = np.clip(h - np.maximum(z, delta), 0.0, None)
    w = w0 + config.jet_spread * s
    axial = u0 * np.sqrt(w0 / w) * np.exp(-((rho - ring) ** 2) / w**2)
    out = np.zeros_like(p)
    wall = z < delta
    out[:, 2] = -axial * np.where(wall, z / delta, 1.0)
    radial = np.where(wall, axial / (2.0 * delta), 0.0)
    out[:, 0] = radial * p[:, 0]
    out[:, 1] = radial * p[:, 1]
    return out


def acceleration(velocity, air, diameter_m, mass_kg, charge_c, field, config: DropletConfig) -> np.ndarray:
    """dv/dt (m/s^2) of eq. 24 for droplets: drag (eqs. 21-22) + q E / m + g.

    Parameters
    ----------
    velocity, air, field : (n, 3) float
        Droplet velocity and air velocity (m/s), electric field (V/m).
    diameter_m, mass_kg, charge_c : (n,) float
    config : DropletConfig
        Air density and viscosity, gravity.
    """
    rel = air - velocity
    speed = np.linalg.norm(rel, axis=1)
    re = diameter_m * speed * config.air_density_kg_m3 / config.air_viscosity_pa_s
    drag = (3.0 * math.pi * config.air_viscosity_pa_s * diameter_m * drag_factor(re))[:, None] * rel
    return (drag + charge_c[:, None] * field) / mass_kg[:, None] + np.asarray(config.gravity_m_s2)


def integrate(
    position_m,
    velocity_m_s,
    diameter_m,
    mass_kg,
    charge_c,
    config: DropletConfig,
    *,
    field=True,
    air=True,
    steps: int | None = None,
    record_every: int = 0,
):
    """Fixed-step explicit Euler (eq. 24) until every droplet has landed on z = 0, left, or timed out.

    Parameters
    ----------
    position_m, velocity_m_s : (n, 3) float
    diameter_m, mass_kg, charge_c : (n,) float
    config : DropletConfig
    field, air : bool
        Include the electrostatic force / the air (mean + turbulent); off: still air, no field.
    steps : int, optional
        Stop after this many steps (default: ``max_time_s / dt_s``).
    record_every : int
        Keep positions and velocities every this many steps (0: not kept).

    Returns
    -------
    landing_m : (n, 3) float
        Where each droplet crossed z = 0 (NaN if it did not).
    time_s : (n,) float
        Flight time (to landing, or to the end).
    history : list of (t, positions (n, 3), velocities (n, 3))
        The recorded states (empty unless ``record_every``).
    """
    x = np.array(position_m, float)
    v = np.array(velocity_m_s, float)
    n = len(x)
    dt = config.dt_s
    total = round(config.max_time_s / dt) if steps is None else int(steps)
    _check_steps(config, n, total)
    rng = np.random.default_rng(config.seed)
    eddy_steps = max(1, round(config.eddy_time_s / dt))
    turb = np.zeros((n, 3))
    landing = np.full((n, 3), np.nan)
    time = np.full(n, total * dt)
    active = np.arange(n)
    voltage = config.voltage_kv * 1000.0
    rb, h = config.cup_radius_mm / 1000.0, config.standoff_mm / 1000.0
    far = 3.0 * h
    history = []
    for step in range(total):
        if record_every and step % record_every == 0:
            history.append((step * dt, x.copy(), v.copy()))
        if not len(active):
            break
        xa, va = x[active], v[active]
        u = np.zeros_like(xa)
        if air:
            u = jet_air(xa, config)
            if config.turbulence_intensity > 0:
                if step % eddy_steps == 0:
                    turb[active] = rng.standard_normal((len(active), 3))
                u = u + turb[active] * (config.turbulence_intensity * np.linalg.norm(u, axis=1))[:, None]
        e = bell_field(xa, voltage, rb, h) if field and voltage else np.zeros_like(xa)
        acc = acceleration(va, u, diameter_m[active], mass_kg[active], charge_c[active], e, config)
        x_new = xa + dt * va
        v[active] = va + dt * acc
        x[active] = x_new
        down = x_new[:, 2] <= 0.0
        if down.any():
            frac = xa[down, 2] / np.maximum(xa[down, 2] - x_new[down, 2], 1e-300)
            landing[active[down]] = xa[down] + frac[:, None] * (x_new[down] - xa[down])
            time[active[down]] = (step + frac) * dt
        gone = down | (np.linalg.norm(x_new[:, :2], axis=1) > far) | (x_new[:, 2] > h + 2.0 * rb)
        time[active[gone & ~down]] = (step + 1) * dt
        active = active[~gone]
    if record_every:
        history.append((min(total, step + 1) * dt, x.copy(), v.copy()))
    return landing, time, history


def simulate_droplets(config: DropletConfig | None = None) -> DropletResult:
    """Droplets from a rotary bell to a grounded plate: landing points and transfer efficiency.

    The cup's edge lies at height H (``standoff_mm``) above the plate z = 0, the bell's axis is the z axis
    pointing down. Droplet sizes are log-normal, charges proportional to mass, start angles uniform: all drawn
    from ``seed``.
    """
    config = DropletConfig() if config is None else config
    rng = np.random.default_rng(config.seed)
    n = int(config.count)
    diameter = config.diameter_um * 1e-6 * np.exp(math.log(config.diameter_gsd) * rng.standard_normal(n))
    mass = config.density_kg_m3 * math.pi / 6.0 * diameter**3
    charge = config.charge_to_mass_c_kg * mass * (1.0 if config.voltage_kv >= 0 else -1.0)
    angle = rng.uniform(0.0, 2.0 * math.pi, n)
    rb, h = config.cup_radius_mm / 1000.0, config.standoff_mm / 1000.0
    radial = np.stack([np.cos(angle), np.sin(angle), np.zeros(n)], axis=1)
    tangent = np.stack([-np.sin(angle), np.cos(angle), np.zeros(n)], axis=1)
    position = radial * rb + np.array([0.0, 0.0, h])
    rim = config.speed_krpm * 1000.0 * 2.0 * math.pi / 60.0 * rb
    velocity = tangent * rim
    tau = mass.min() / (3.0 * math.pi * config.air_viscosity_pa_s * diameter.min())
    if config.dt_s > 0.5 * tau:
        log.warning(
            "droplet time step %.2g s is large against the smallest droplet's relaxation time %.2g s", config.dt_s, tau
        )
    landing, time, _ = integrate(position, velocity, diameter, mass, charge, config)
    landed = ~np.isnan(landing[:, 0])
    if config.plate_radius_mm is not None:
        landed &= np.linalg.norm(landing[:, :2], axis=1) * 1000.0 <= config.plate_radius_mm
    volume = mass / config.density_kg_m3 * 1e9
    efficiency = float(volume[landed].sum() / volume.sum())
    landing_mm = np.where(landed[:, None], landing[:, :2] * 1000.0, np.nan)
    log.info("droplets: %d of %d landed, transfer efficiency %.3f", int(landed.sum()), n, efficiency)
    return DropletResult(landing_mm, landed, diameter * 1e6, volume, time, efficiency, config)


def landing_density(result: DropletResult, cell_mm: float | None = None, half_width_mm: float | None = None):
    """The deposition pattern of the landed droplets as a density grid (1/mm^2, integral 1 over the landed).

    Parameters
    ----------
    result : DropletResult
    cell_mm : float, optional
        Grid cell side; default: the half width / 20.
    half_width_mm : float, optional
        Grid half side; default: the 99th percentile of the landing radius.

    Returns
    -------
    x_mm, y_mm : (k,) float
        Cell centres (flattened grid).
    density : (k,) float
        Volume-weighted share of landed paint per cell area.
    """
    pts = result.landing_mm[result.landed]
    w = result.volume_mm3[result.landed]
    if not len(pts):
        raise ConfigError("no droplet landed: nothing to make a pattern of")
    half = float(np.quantile(np.linalg.norm(pts, axis=1), 0.99)) if half_width_mm is None else half_width_mm
    cell = half / 20.0 if cell_mm is None else float(cell_mm)
    if not (math.isfinite(cell) and cell > 0 and math.isfinite(half) and half > 0):
        raise ConfigError(f"cell_mm and half_width_mm must be positive numbers, got {cell_mm!r}, {half_width_mm!r}")
    check_work(
        (2 * half / cell) ** 2,
        1e8,
        "grid cells",
        "cell_mm",
        cell,
        f"half width {half:.4g} mm",
        f"use cell_mm >= {2 * half / 1e4:.3g}",
    )
    edges = np.arange(-half, half + cell / 2, cell)
    hist, ex, ey = np.histogram2d(pts[:, 0], pts[:, 1], bins=[edges, edges], weights=w)
    cx, cy = 0.5 * (ex[1:] + ex[:-1]), 0.5 * (ey[1:] + ey[:-1])
    gx, gy = np.meshgrid(cx, cy, indexing="ij")
    return gx.ravel(), gy.ravel(), (hist / (w.sum() * cell * cell)).ravel()
