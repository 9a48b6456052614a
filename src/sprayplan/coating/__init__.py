"""The ``coating`` stage: spray patterns, film thickness from a plan, reports, spacing, and the droplet model.

Modules: ``patterns`` (deposition models), ``process`` (process parameters and TOML presets), ``thickness``
(film on a part from a plan, with ``sampling`` and ``occlusion``), ``report`` (statistics against a spec),
``spacing`` (stroke spacing and gun speed for a target), ``fitting`` (patterns from measurements or
simulations), ``droplet`` (electrostatic rotary-bell droplets, seed 003 section 4).
"""

from sprayplan.coating.droplet import (
    DropletConfig,
    DropletResult,
    bell_field,
    bell_potential,
    drag_factor,
    landing_density,
    simulate_droplets,
)
from sprayplan.coating.fitting import PatternFit, fit_density, fit_droplets, fit_stroke_profile
from sprayplan.coating.patterns import KINDS, SprayPattern, pattern_from_dict
from sprayplan.coating.process import (
    BellSettings,
    Process,
    StrokeOverride,
    list_presets,
    load_preset,
    process_from_dict,
    process_to_toml,
)
from sprayplan.coating.report import (
    boundary_distance,
    coating_report,
)
from sprayplan.coating.sampling import GunSamples, SurfaceSamples, gun_samples, surface_samples
from sprayplan.coating.spacing import (
    SpacingChoice,
    choose_spacing,
    choose_spacing_and_speed,
    film_across,
    ripple_cv,
    speed_for_target,
)
from sprayplan.coating.thickness import (
    CoatingConfig,
    CoatingResult,
    deposit_matrix,
    film_rate,
    shot_thickness,
    simulate,
)

__all__ = [
    "KINDS",
    "BellSettings",
    "CoatingConfig",
    "CoatingResult",
    "DropletConfig",
    "DropletResult",
    "GunSamples",
    "PatternFit",
    "Process",
    "SpacingChoice",
    "SprayPattern",
    "StrokeOverride",
    "SurfaceSamples",
    "bell_field",
    "bell_potential",
    "boundary_distance",
    "choose_spacing",
    "choose_spacing_and_speed",
    "coating_report",
    "deposit_matrix",
    "drag_factor",
    "film_across",
    "film_rate",
    "fit_density",
    "fit_droplets",
    "fit_stroke_profile",
    "gun_samples",
    "landing_density",
    "list_presets",
    "load_preset",
    "pattern_from_dict",
    "process_from_dict",
    "process_to_toml",
    "ripple_cv",
    "shot_thickness",
    "simulate",
    "simulate_droplets",
    "speed_for_target",
    "surface_samples",
]
