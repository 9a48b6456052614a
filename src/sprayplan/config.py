"""Typed configuration of each stage, with every default in one place.

Each stage takes one frozen dataclass; :func:`config_from_dict` builds one from a TOML table (keys as the field
names, units in the names), rejecting unknown keys so that a typo does not pass silently.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from sprayplan.errors import ConfigError

FILL_MODES = ("even", "point", "line")


@dataclass(frozen=True)
class LoadConfig:
    """How a part file is read: its length unit, its up axis, and the region to keep."""

    units: str = "mm"
    up: str = "z"
    region: str | None = None


@dataclass(frozen=True)
class TargetsConfig:
    """Target points (seed 000, section 2).

    Attributes
    ----------
    fill : {"even", "point", "line"}
        ``even``: Poisson-disk sampling, no two targets closer than the spacing. ``point`` / ``line``: the seed's
        DFS triangle filling at ``h_min_mm``, plus the mesh's vertices, then compressed to the spacing.
    spacing_mm : float or None
        Target spacing d. None: derived from the spray circle and overlap by the inverse of eq. 6.
    spray_radius_mm : float
        Radius r of the spray circle at the working distance (seed 000: 50 mm).
    overlap : float
        Overlap ratio p of neighbouring spray circles (seed 000: 0.4).
    compress : {"surface", "grid", "none"}
        ``grid`` is eq. 7 as printed (points snapped to the grid, off the surface); ``surface`` keeps one real
        point per grid cell.
    h_min_mm : float or None
        The DFS filling's minimum triangle height h_min (eqs. 1-3); None: half the spacing.
    normals : {"face", "pca"}
        Even fill: each point takes its face's normal (``face``), or a PCA fit over the targets within
        ``normal_radius_mm`` (``pca``: smoother on noisy scan meshes). The DFS fills always follow the seed.
    normal_radius_mm : float or None
        Neighbourhood radius r for PCA normals; None: twice the spacing.
    orient : {"mesh", "centroid", "propagate"} or None
        How normals are turned outward; None: ``mesh`` for meshes, ``propagate`` for point clouds.
    seed : int
        Random seed of the even sampling.
    """

    fill: str = "even"
    spacing_mm: float | None = None
    spray_radius_mm: float = 50.0
    overlap: float = 0.4
    compress: str = "surface"
    h_min_mm: float | None = None
    normals: str = "face"
    normal_radius_mm: float | None = None
    orient: str | None = None
    seed: int = 0

    def __post_init__(self):
        from sprayplan.surface.compress import COMPRESS_METHODS
        from sprayplan.surface.normals import ORIENT_METHODS

        if self.fill not in FILL_MODES:
            raise ConfigError(f"fill must be one of {', '.join(FILL_MODES)}, got {self.fill!r}")
        if self.compress not in COMPRESS_METHODS:
            raise ConfigError(f"compress must be one of {', '.join(COMPRESS_METHODS)}, got {self.compress!r}")
        if self.normals not in ("face", "pca"):
            raise ConfigError(f"normals must be 'face' or 'pca', got {self.normals!r}")
        if self.orient is not None and self.orient not in ORIENT_METHODS:
            raise ConfigError(f"orient must be one of {', '.join(ORIENT_METHODS)}, got {self.orient!r}")
        for name in ("spacing_mm", "h_min_mm", "normal_radius_mm"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value > 0):
                raise ConfigError(f"{name} must be a positive number, got {value}")
        if not (math.isfinite(self.spray_radius_mm) and self.spray_radius_mm > 0):
            raise ConfigError(f"spray_radius_mm must be a positive number, got {self.spray_radius_mm}")
        if not 0.0 <= self.overlap < 1.0:
            raise ConfigError(f"overlap must be in [0, 1), got {self.overlap}")

    @property
    def spacing(self) -> float:
        """The target spacing d in mm: as set, or from the spray radius and overlap (inverse of eq. 6)."""
        if self.spacing_mm is not None:
            return float(self.spacing_mm)
        from sprayplan.surface.coverage import spacing_for_overlap

        return spacing_for_overlap(self.overlap, self.spray_radius_mm)


def config_from_dict(cls, table: dict):
    """Build a stage config from a mapping, rejecting unknown keys.

    Parameters
    ----------
    cls : type
        One of the config dataclasses.
    table : dict
        Values by field name.
    """
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(table) - names)
    if unknown:
        raise ConfigError(f"unknown {cls.__name__} key(s): {', '.join(unknown)}; known: {', '.join(sorted(names))}")
    return cls(**table)
