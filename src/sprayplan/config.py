"""Typed configuration of each stage, with every default in one place.

Each stage takes one frozen dataclass; :func:`config_from_dict` builds one from a TOML table (keys as the field
names, units in the names), rejecting unknown keys so that a typo does not pass silently.

Bounds of work (``sprayplan.checks``; issue 13: no setting may ask for more than a 2-core, 24 GiB machine has):
``paths.layers`` and the layers a spacing makes at most 10000; ``paths.edge_passes`` at most 100;
``paths.points_per_section`` at most 100000; steps and spacings at least 0.01 mm; at most 5e6 waypoints,
2e7 target candidates or filling points and 2e7 film samples on the part (checked by each stage before it
allocates, naming the setting, the part's size and the value accepted); ``output.samples`` at most 1e6;
``coating.batch`` at most 65536, ``occlusion_pixels`` 1024, ``workers`` 64. A whole car body at 40 mm
spacing and 5 mm steps (about 60 000 waypoints) is far inside every bound.
"""

from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass

from sprayplan.checks import (  # noqa: F401 - MIN_DWELL and the bounds are part of this API
    MAX_COORDINATE_MM,
    MAX_EDGE_PASSES,
    MAX_LAYERS,
    MAX_POINTS_PER_SECTION,
    MAX_REPORT_SAMPLES,
    MIN_DWELL,
    MIN_STEP_MM,
    check_dwell_bounds,
    number_text,
)
from sprayplan.errors import ConfigError
from sprayplan.errors import PartFileError as _PartFileError

FILL_MODES = ("even", "point", "line")
UNITS = ("mm", "cm", "m", "in")
UP_AXES = ("z", "y", "x")
MODES = ("paths", "points")
TOURS = ("auto", "ga", "exact", "keep")
ROBOTS = ("gantry-ur5", "gantry-ur5e")
SPEED_ALONG = ("surface", "tcp")


def _fail(cls, name: str, wanted: str, value) -> ConfigError:
    return ConfigError(f"{cls.SECTION}.{name} must be {wanted}, got {value!r}")


class Section:
    """Base of every config section: checks each field against its annotation before the section's own checks.

    ``float`` fields take a finite number (not a bool, not a string) and are stored as float, at most
    ``checks.MAX_COORDINATE_MM`` in size for a length (``_mm``) or a speed (``_mm_s``); ``int`` fields a
    whole number (stored as int); ``bool`` fields only true or false; ``str`` fields only a string. ``X | None``
    also takes None. Other annotations are left to the section's ``_check``. A bad value raises a one-line
    :class:`~sprayplan.errors.ConfigError` naming ``section.key`` and what it takes.
    """

    SECTION = "config"

    def __post_init__(self):
        for f in dataclasses.fields(self):
            kind = str(f.type).replace(" ", "")
            optional = kind.endswith("|None")
            kind = kind.removesuffix("|None")
            value = getattr(self, f.name)
            if value is None and optional:
                continue
            converted = _typed(type(self), f.name, kind, value, optional)
            if kind == "float" and f.name.endswith(("_mm", "_mm_s")) and abs(converted) > MAX_COORDINATE_MM:
                unit = "mm/s" if f.name.endswith("_s") else "mm"
                raise _fail(type(self), f.name, f"at most {MAX_COORDINATE_MM:g} {unit} (10 km)", value)
            if converted is not value:
                object.__setattr__(self, f.name, converted)
        self._check()

    def _check(self) -> None:
        """Range and consistency checks of the section (types are checked already)."""


def _typed(cls, name: str, kind: str, value, optional: bool):
    tail = " or none" if optional else ""
    if kind == "float":
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise _fail(cls, name, "a finite number" + tail, value)
        return float(value)
    if kind == "int":
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise _fail(cls, name, "a whole number" + tail, value)
        if int(value) != value:
            raise _fail(cls, name, "a whole number" + tail, value)
        return int(value)
    if kind == "bool":
        if not isinstance(value, bool):
            raise _fail(cls, name, "true or false", value)
        return value
    if kind == "str":
        if not isinstance(value, str):
            raise _fail(cls, name, "a string" + tail, value)
        return value
    return value


def _choice(cls, name: str, value, allowed) -> None:
    if value not in allowed:
        raise _fail(cls, name, "one of " + ", ".join(map(str, allowed)), value)


def _at_least(cls, name: str, value, low: float, *, strict: bool = False) -> None:
    if value is not None and not (value > low if strict else value >= low):
        raise _fail(cls, name, f"a number {'>' if strict else '>='} {low:g}", value)


def _within(cls, name: str, value, low: float, high: float) -> None:
    if value is not None and not low <= value <= high:
        raise _fail(cls, name, f"a number from {low:g} to {high:g}", value)


def _at_most(cls, name: str, value, high: float) -> None:
    """The upper bound of a count or the lower bound's partner: names the key and the largest value accepted."""
    if value is not None and not value <= high:
        raise _fail(cls, name, f"at most {number_text(high)}", value)


@dataclass(frozen=True)
class LoadConfig(Section):
    """How a part file is read (``[load]``): its length unit, its up axis, and the region to keep.

    Attributes
    ----------
    units : {"mm", "cm", "m", "in"}
    up : {"z", "y", "x"}
        The file's up axis, turned to +z.
    region : str or None
        A region expression (``sprayplan.surface.region``), in mm in the part frame; None: the whole part.
    mask : list of str
        Regions left unpainted (``plan --mask``; ``surface.region.mask_out``): each a region expression in mm
        in the part frame; the part inside them stays an obstacle for the robots, and the film is judged on
        the rest. Empty: nothing masked.
    """

    SECTION = "load"
    units: str = "mm"
    up: str = "z"
    region: str | None = None
    mask: tuple = ()

    def _check(self):
        _choice(LoadConfig, "units", self.units, UNITS)
        _choice(LoadConfig, "up", self.up, UP_AXES)
        if self.region is not None and not self.region.strip():
            raise _fail(LoadConfig, "region", "a region expression or none", self.region)
        masks = self.mask
        if isinstance(masks, str) or not isinstance(masks, (list, tuple)) or not all(isinstance(m, str) for m in masks):
            raise _fail(LoadConfig, "mask", "a list of region expressions", masks)
        from sprayplan.errors import RegionError
        from sprayplan.surface.region import parse_masks

        try:
            parse_masks(masks)
        except RegionError as exc:
            raise ConfigError(f"load.mask: {exc}") from None
        object.__setattr__(self, "mask", tuple(masks))


@dataclass(frozen=True)
class TargetsConfig(Section):
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

    SECTION = "targets"
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

    def _check(self):
        if self.seed < 0:
            raise _fail(TargetsConfig, "seed", "a whole number >= 0", self.seed)
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
        for name in ("spacing_mm", "h_min_mm"):
            _at_least(TargetsConfig, name, getattr(self, name), MIN_STEP_MM)
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
        where = f"[{cls.SECTION}]" if hasattr(cls, "SECTION") else cls.__name__
        raise ConfigError(f"{where}: unknown key(s) {', '.join(unknown)}; known: {', '.join(sorted(names))}")
    return cls(**table)


@dataclass(frozen=True)
class PathConfig(Section):
    """Spray paths by slicing (seed 003 sections 2-3; spacing from seed 000's eq. 6).

    Attributes
    ----------
    direction : str or tuple
        The slicing planes' normal: ``"auto"`` (across the part's longest principal axis, so strokes run
        along it), ``"x"``, ``"y"``, ``"z"``, or a vector ``(dx, dy, dz)``.
    spacing_mm : float or None
        Distance between adjacent strokes; None: from the spray radius and overlap (inverse of eq. 6).
    layers : int or None
        Instead of a spacing: this many equally spaced planes across the part (seed 003 uses 20).
    spray_radius_mm, overlap : float
        The spray circle and the overlap of neighbouring strokes (seed 000: 50 mm, 0.4).
    spacing_mode : {"surface", "uniform"}
        ``surface``: each plane is placed so that its section runs ``spacing_mm`` from the previous one
        measured on the part (median point-to-polyline distance), so layers are tighter where the surface
        turns away from the slicing direction; ``uniform``: planes equally spaced (the seed's slicing).
    standoff_mm : float
        Gun tip to surface along the normal, H in 003's eq. ``O_i = Q_i + H n_i`` (default 113 mm: seed 000's
        T_dis, where its spray circle has a 50 mm radius).
    edge_margin_mm : float or None
        Lead-in / lead-out past the part's edge at both ends of every stroke; None: the spray radius.
    step_mm : float
        Distance between waypoints along a stroke.
    split_gap_mm : float or None
        A stroke is split (spray off across) where the surface has a gap wider than this; None: the spray
        diameter. Narrower gaps are sprayed across.
    split_angle_deg : float or None
        Strokes are split at sharp feature points (003 section 2.1.3) whose tangent turns by more than this;
        None: never.
    streamline_deg : tuple of float or None
        Angle-method streamlining thresholds [alpha_min, alpha_max] (003 section 2.1.1), in degrees; None: off
        (the default for meshes, whose sections are exact; on for clouds).
    points_per_section : int or None
        Sample each section piece at this many points (003 eq. 13, d_m = length / num) instead of every
        ``step_mm``.
    interpolate : {"none", "line", "arc"}
        With ``points_per_section``: line or circular-arc interpolation of the gun path between the sampled
        points, every ``step_mm`` (003 section 3.2.3).
    slab_mm : float or None
        Point clouds: half-thickness of the slab around each plane; None: twice the cloud's median spacing.
    cloud_normals : {"triangles", "plane"}
        Point clouds: normals at section points by the neighbour-triangle method (003 section 3.2.2) or by a
        k-nearest-neighbour plane fit.
    cloud_smooth_mm : float or None
        Point clouds: move each point onto the least-squares plane of its neighbours within this radius before
        slicing (003 section 2.2.3); None: no smoothing.
    cloud_normal_smooth_mm : float or None
        Point clouds: average the section normals over this arc length either side (a scan's normals are
        noisy, and the gun would swing with them); None: half the spray radius; 0: off.
    gun_smooth_mm : float or None
        The gun's axis along a stroke: the normals averaged with a triangle weight over this arc length either
        side (two box averages of half this width), so that the gun turns through a crease or a feature line
        over about a spray diameter instead of within one step (a snap the wrist cannot make at the process
        speed); the points stay on the surface, the gun aims at them from the standoff along the smoothed
        axis. None: the spray's diameter (twice ``spray_radius_mm``: on the BMW body in ``line3`` the timed
        cycle 2,232 -> 1,801 s against 1,954 s with the radius, docs/benchmarks.md); 0: the gun follows every
        normal.
    rim_mm : float or None
        An end of a stroke, at most this long, whose normals turn more than 45 degrees away from the face's (a
        hemmed or rolled edge, the side of a thin panel) is not followed: the stroke leaves the face along its
        tangent and the lead-out passes the rim's edge by ``edge_margin_mm``. None: half the spray radius;
        0: follow every end.
    edge_passes : "auto" or int
        Extra spray passes past the first and the last layer, the spacing apart on the surface extended flat
        beyond the edge (``on_part`` False), so that the film does not thin out along the part's edges that
        run with the strokes (the ends of the strokes are covered by ``edge_margin_mm``). ``auto``: at each
        end, as many as still put paint on the part, judged by the spray radius and the measured distance from
        the outer layer to the part's edge; a number: that many at each end. With passes, the layers keep the
        spacing up to the far edge; with 0 the march closes the part with a last layer at the far edge (closer
        than the spacing) when more than half a spacing would be left bare.
    """

    SECTION = "paths"
    direction: str | tuple = "auto"
    spacing_mm: float | None = None
    layers: int | None = None
    spray_radius_mm: float = 50.0
    overlap: float = 0.4
    spacing_mode: str = "surface"
    standoff_mm: float = 113.0
    edge_margin_mm: float | None = None
    step_mm: float = 10.0
    split_gap_mm: float | None = None
    split_angle_deg: float | None = 60.0
    streamline_deg: tuple | None = None
    points_per_section: int | None = None
    interpolate: str = "none"
    slab_mm: float | None = None
    cloud_normals: str = "triangles"
    cloud_smooth_mm: float | None = None
    cloud_normal_smooth_mm: float | None = None
    gun_smooth_mm: float | None = None
    rim_mm: float | None = None
    edge_passes: str | int = "auto"

    def _check(self):
        if self.edge_passes != "auto":
            value = self.edge_passes
            if (
                isinstance(value, bool)
                or not isinstance(value, (int, float))
                or not math.isfinite(value)
                or int(value) != value
                or value < 0
            ):
                raise ConfigError(f"edge_passes must be auto or a whole number >= 0, got {self.edge_passes!r}")
            _at_most(PathConfig, "edge_passes", value, MAX_EDGE_PASSES)
            object.__setattr__(self, "edge_passes", int(self.edge_passes))
        if self.cloud_normals not in ("triangles", "plane"):
            raise ConfigError(f"cloud_normals must be triangles or plane, got {self.cloud_normals!r}")
        if isinstance(self.direction, str):
            if self.direction not in ("auto", "x", "y", "z"):
                raise ConfigError(f"direction must be auto, x, y, z or a vector, got {self.direction!r}")
        else:
            wanted = "auto, x, y, z or three finite numbers, not all 0"
            try:
                if isinstance(self.direction, (str, bytes)) or any(isinstance(v, (bool, str)) for v in self.direction):
                    raise TypeError
                vector = tuple(float(v) for v in self.direction)
            except (TypeError, ValueError):
                raise _fail(PathConfig, "direction", wanted, self.direction) from None
            if len(vector) != 3 or not all(math.isfinite(v) for v in vector) or not any(vector):
                raise _fail(PathConfig, "direction", wanted, self.direction)
            object.__setattr__(self, "direction", vector)
        if self.spacing_mode not in ("surface", "uniform"):
            raise ConfigError(f"spacing_mode must be surface or uniform, got {self.spacing_mode!r}")
        if self.interpolate not in ("none", "line", "arc"):
            raise ConfigError(f"interpolate must be none, line or arc, got {self.interpolate!r}")
        if self.layers is not None and (int(self.layers) != self.layers or self.layers < 1):
            raise ConfigError(f"layers must be a positive whole number, got {self.layers}")
        if self.points_per_section is not None and (
            int(self.points_per_section) != self.points_per_section or self.points_per_section < 2
        ):
            raise ConfigError(f"points_per_section must be a whole number >= 2, got {self.points_per_section}")
        _at_most(PathConfig, "layers", self.layers, MAX_LAYERS)
        _at_most(PathConfig, "points_per_section", self.points_per_section, MAX_POINTS_PER_SECTION)
        if self.layers is not None and self.spacing_mm is not None:
            raise ConfigError("give either layers or spacing_mm, not both")
        for name in ("spacing_mm", "spray_radius_mm", "step_mm", "split_gap_mm", "slab_mm", "cloud_smooth_mm"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value > 0):
                raise ConfigError(f"{name} must be a positive number, got {value}")
        for name in ("spacing_mm", "step_mm"):
            _at_least(PathConfig, name, getattr(self, name), MIN_STEP_MM)
        if self.cloud_normal_smooth_mm is not None and not (
            math.isfinite(self.cloud_normal_smooth_mm) and self.cloud_normal_smooth_mm >= 0
        ):
            raise ConfigError(f"cloud_normal_smooth_mm must be a number >= 0, got {self.cloud_normal_smooth_mm}")
        if self.split_angle_deg is not None and not 0.0 <= self.split_angle_deg <= 180.0:
            raise _fail(PathConfig, "split_angle_deg", "an angle from 0 to 180 degrees or none", self.split_angle_deg)
        if self.gun_smooth_mm is not None and not (math.isfinite(self.gun_smooth_mm) and self.gun_smooth_mm >= 0):
            raise ConfigError(f"gun_smooth_mm must be a number >= 0, got {self.gun_smooth_mm}")
        if self.rim_mm is not None and not (math.isfinite(self.rim_mm) and self.rim_mm >= 0):
            raise ConfigError(f"rim_mm must be a number >= 0, got {self.rim_mm}")
        if self.edge_margin_mm is not None and not (math.isfinite(self.edge_margin_mm) and self.edge_margin_mm >= 0):
            raise ConfigError(f"edge_margin_mm must be a number >= 0, got {self.edge_margin_mm}")
        if not (math.isfinite(self.standoff_mm) and self.standoff_mm >= 0):
            raise ConfigError(f"standoff_mm must be a number >= 0, got {self.standoff_mm}")
        if not 0.0 <= self.overlap < 1.0:
            raise ConfigError(f"overlap must be in [0, 1), got {self.overlap}")
        if self.streamline_deg is not None:
            wanted = "[alpha_min, alpha_max] with 90 <= min <= max <= 180 (degrees)"
            try:
                if isinstance(self.streamline_deg, (str, bytes)) or any(
                    isinstance(v, (bool, str)) for v in self.streamline_deg
                ):
                    raise TypeError
                lo, hi = (float(v) for v in self.streamline_deg)
            except (TypeError, ValueError):
                raise _fail(PathConfig, "streamline_deg", wanted, self.streamline_deg) from None
            if not 90.0 <= lo <= hi <= 180.0:
                raise _fail(PathConfig, "streamline_deg", wanted, self.streamline_deg)
            object.__setattr__(self, "streamline_deg", (lo, hi))

    @property
    def spacing(self) -> float:
        """Stroke spacing in mm: as set, or from the spray radius and overlap (inverse of seed 000's eq. 6)."""
        if self.spacing_mm is not None:
            return float(self.spacing_mm)
        from sprayplan.surface.coverage import spacing_for_overlap

        return spacing_for_overlap(self.overlap, self.spray_radius_mm)

    @property
    def margin(self) -> float:
        """Lead-in / lead-out length, mm."""
        return self.spray_radius_mm if self.edge_margin_mm is None else float(self.edge_margin_mm)

    @property
    def rim(self) -> float:
        """Longest end stretch treated as a rim, mm."""
        return self.spray_radius_mm / 2.0 if self.rim_mm is None else float(self.rim_mm)

    @property
    def gap(self) -> float:
        """Widest gap sprayed across, mm."""
        return 2.0 * self.spray_radius_mm if self.split_gap_mm is None else float(self.split_gap_mm)


@dataclass(frozen=True)
class StationsConfig(Section):
    """Gantry stations (``[stations]``, seed 000 section 5.1).

    Attributes
    ----------
    home_mm : tuple of 3 float
        Where the gantry starts and ends (the seed's "zero").
    platform_z_mm : float or None
        Gantry height; None: the part's flange positions at the middle of the working cylinder.
    seed : int
        Random seed of the circle cover's search.
    """

    SECTION = "stations"
    home_mm: tuple = (0.0, 0.0, 0.0)
    platform_z_mm: float | None = None
    seed: int = 0

    def _check(self):
        home = self.home_mm
        if isinstance(home, (str, bytes)) or not hasattr(home, "__len__") or len(home) != 3:
            raise _fail(StationsConfig, "home_mm", "three numbers", home)
        if any(isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) for v in home):
            raise _fail(StationsConfig, "home_mm", "three finite numbers", home)
        object.__setattr__(self, "home_mm", tuple(float(v) for v in home))
        _at_least(StationsConfig, "seed", self.seed, 0)


@dataclass(frozen=True)
class OrderingConfig(Section):
    """The order of the work inside a station (``[ordering]``, seed 000 section 5.2).

    Attributes
    ----------
    tour : {"auto", "ga", "exact", "keep"}
        Ordering inside a station: of the strokes (``keep``: zig-zag order as sliced) or, in points mode, of
        the targets (``ga``: the seed's genetic algorithm). ``auto`` is a deterministic descent (nearest
        neighbour, 2-opt, Or-opt), so that a plan repeats exactly on any machine.
    seed : int
        Random seed of the tour solvers.
    """

    SECTION = "ordering"
    tour: str = "auto"
    seed: int = 0

    def _check(self):
        _choice(OrderingConfig, "tour", self.tour, TOURS)
        _at_least(OrderingConfig, "seed", self.seed, 0)


@dataclass(frozen=True)
class KinematicsConfig(Section):
    """The robot and its inverse kinematics (``[kinematics]``, seed 000 sections 3-4).

    Attributes
    ----------
    robot : {"gantry-ur5", "gantry-ur5e"}
        Seed 000's three-axis gantry carrying a UR5 (or a UR5e).
    robot_file : str or None
        A robot TOML file (``robots.model.load_robot``'s keys, e.g. ``preset = "ur5"`` and the joints' speed
        and acceleration limits ``max_velocity_deg_s``, ``max_acceleration_deg_s2``) for the arm on the gantry,
        in place of ``robot``'s preset (``plan --robot-file``); a UR-type six-axis arm (the gantry's inverse
        kinematics is UR's), whose base and tool are the gantry's and the gun's, so the file sets neither.
        A path relative to the working folder.
    tool : str
        Gun preset (``wa101``).
    position_tol_mm, axis_tol_deg : float
        Allowed errors of the SQP fallback (eqs. 21-22; seed: 5 mm, 5 degrees).
    k_d : float
        Weight of gantry travel in eq. 20, rad^2/mm^2 (0.1: 3.2 mm of travel costs as much as 1 rad).
    processes : int or None
        Processes that share the job's work that splits into independent pieces (the joint solves, a station
        at a time, in the kinematics stage and the touch-ups; the report's pictures): the job's own and up to
        one helper on the second core (``sprayplan.parallel``). Default: 2 on a machine with 2 or more cores
        (1 in a batch, which runs jobs side by side); 1 keeps everything in the job's process. The plan and
        its files are the same either way.
    """

    SECTION = "kinematics"
    robot: str = "gantry-ur5"
    tool: str = "wa101"
    position_tol_mm: float = 5.0
    axis_tol_deg: float = 5.0
    k_d: float = 0.1
    robot_file: str | None = None
    processes: int | None = None

    def _check(self):
        _choice(KinematicsConfig, "robot", self.robot, ROBOTS)
        if self.robot_file is not None:
            self.arm_model()  # a missing or broken file, or a bad value in it, is an error now
        _choice(KinematicsConfig, "tool", self.tool, ("wa101",))
        _at_least(KinematicsConfig, "position_tol_mm", self.position_tol_mm, 0, strict=True)
        _within(KinematicsConfig, "axis_tol_deg", self.axis_tol_deg, 1e-9, 90.0)
        _at_least(KinematicsConfig, "k_d", self.k_d, 0)
        _within(KinematicsConfig, "processes", self.processes, 1, 2)

    @property
    def arm(self) -> str:
        """The arm on the gantry: ``ur5`` or ``ur5e``."""
        return self.robot.removeprefix("gantry-")

    def arm_model(self):
        """The arm on the gantry (a ``robots.model.RobotModel``): ``robot_file``'s, else ``robot``'s preset.

        Raises
        ------
        ConfigError
            ``robot_file`` missing, broken, with a bad value (a limit of zero, NaN, negative), not a UR-type
            six-axis arm, or setting the base or the tool; the message names the setting and the file.
        """
        import numpy as np

        from sprayplan.robots.model import load_robot
        from sprayplan.robots.ur_ik import check_ur_model

        if self.robot_file is None:
            return load_robot(self.arm)
        where = f"{KinematicsConfig.SECTION}.robot_file"
        try:
            model = load_robot(self.robot_file, where)
            check_ur_model(model)
        except (ConfigError, _PartFileError) as exc:
            text = str(exc)
            raise ConfigError(
                f"{where}: {text}" if self.robot_file in text else f"{where} {self.robot_file}: {text}"
            ) from None
        if not (np.allclose(model.base2world, np.eye(4)) and np.allclose(model.tool2flange, np.eye(4))):
            raise ConfigError(
                f"{where} {self.robot_file}: base_* and tool_* keys are not taken on the gantry (its carriage is the "
                "base, [kinematics] tool the gun)"
            )
        return model


@dataclass(frozen=True)
class MotionConfig(Section):
    """Speeds (``[motion]``): the gun's while spraying, the arm's between strokes, the gantry's.

    Attributes
    ----------
    gun_speed_mm_s, transfer_speed_mm_s, platform_speed_mm_s : float
        Spraying, spray-off moves of the arm, and the gantry.
    speed_along : {"surface", "tcp"}
        What moves at ``gun_speed_mm_s`` while spraying: the paint's contact point on the surface (the gun
        tip then speeds up over convex bends and slows down in concave ones; plan.json gives the tip's speed
        per waypoint), or the gun tip itself (one speed per stroke). See ``sprayplan.paths.speed``.
    max_speed_ratio : float
        With ``surface``: the gun tip's speed stays within [v / ratio, v ratio].
    """

    SECTION = "motion"
    gun_speed_mm_s: float = 400.0
    transfer_speed_mm_s: float = 1000.0
    platform_speed_mm_s: float = 250.0
    speed_along: str = "surface"
    max_speed_ratio: float = 3.0

    def _check(self):
        for name in ("gun_speed_mm_s", "transfer_speed_mm_s", "platform_speed_mm_s"):
            _at_least(MotionConfig, name, getattr(self, name), 0, strict=True)
        _choice(MotionConfig, "speed_along", self.speed_along, SPEED_ALONG)
        _at_least(MotionConfig, "max_speed_ratio", self.max_speed_ratio, 1)


@dataclass(frozen=True)
class FilmConfig(Section):
    """The paint and the film model (``[coating]``, seed 003 sections 4-5).

    Attributes
    ----------
    process : str
        Spray process preset or TOML file (``seed000_circle``, ``seed000_flat``, ``bell003``): the pattern,
        flow, solids and transfer efficiency used to predict the film.
    thickness_um : float or None
        A dry-film target: when set, the stroke spacing and the gun speed are chosen to meet it (the spacing
        that makes the film across parallel strokes flattest, the speed that puts its mean on target), in
        place of ``[paths] spacing_mm`` and ``[motion] gun_speed_mm_s``.
    tolerance_um : float
        The spec is ``thickness_um +- tolerance_um`` (default 5, seed 003's); without a target the film is
        judged against seed 003's 50 +- 5 um.
    flow_ml_min : float or None
        The paint's wet flow, mL/min, in place of the process's own (None: the process's). With a film target
        the gun speed follows it (the film is flow over speed), so a lower flow paints the same film slower.
        A cell plan may lower it further to the speeds its robots make (``[timing] fit_flow``).
    max_step_mm, occlusion, occlusion_step_mm, occlusion_pixels, sample_edge_mm, search_factor, batch, workers
        The film simulation's numerical settings (``sprayplan.coating.CoatingConfig``; None: its defaults).
    """

    SECTION = "coating"
    process: str = "seed000_circle"
    thickness_um: float | None = None
    tolerance_um: float = 5.0
    flow_ml_min: float | None = None
    max_step_mm: float | None = None
    occlusion: str = "auto"
    occlusion_step_mm: float | None = None
    occlusion_pixels: int = 16
    sample_edge_mm: float | None = None
    search_factor: float = 1.15
    batch: int = 4096
    workers: int | None = None

    def _check(self):
        if not self.process.strip():
            raise _fail(FilmConfig, "process", "a preset name or a .toml file", self.process)
        import os

        if not (self.process.endswith(".toml") or os.sep in self.process):
            from sprayplan.coating.process import list_presets

            known = list_presets()
            if self.process not in known:
                raise _fail(FilmConfig, "process", f"one of {', '.join(known)} or a .toml file", self.process)
        _at_least(FilmConfig, "thickness_um", self.thickness_um, 0, strict=True)
        _at_least(FilmConfig, "tolerance_um", self.tolerance_um, 0)
        if self.flow_ml_min is not None and not (math.isfinite(self.flow_ml_min) and self.flow_ml_min > 0):
            raise _fail(FilmConfig, "flow_ml_min", "a finite number > 0", self.flow_ml_min)
        _at_least(FilmConfig, "workers", self.workers, 1)
        try:
            self.simulation(MotionConfig())
        except ConfigError as exc:
            raise ConfigError(f"coating.{exc}") from None

    def simulation(self, motion: MotionConfig):
        """The film simulation's settings (``coating.CoatingConfig``), with the speeds of ``motion``."""
        from sprayplan.coating.thickness import CoatingConfig

        return CoatingConfig(
            max_step_mm=self.max_step_mm,
            occlusion=self.occlusion,
            occlusion_step_mm=self.occlusion_step_mm,
            occlusion_pixels=self.occlusion_pixels,
            speed_along=motion.speed_along,
            max_speed_ratio=motion.max_speed_ratio,
            sample_edge_mm=self.sample_edge_mm,
            search_factor=self.search_factor,
            batch=self.batch,
            workers=self.workers,
        )

    @property
    def tolerance(self) -> float:
        """The tolerance the tuning aims for, um: as set, or 5 % of the target when set to 0."""
        target = 50.0 if self.thickness_um is None else self.thickness_um
        return self.tolerance_um if self.tolerance_um > 0 else 0.05 * target


@dataclass(frozen=True)
class RefineConfig(Section):
    """Refinement of a planned program against its film (``[tuning]``): speeds, touch-ups, added stations.

    Attributes
    ----------
    tune_speed : bool
        With a film target: after planning, give every waypoint a time factor (``Stroke.dwell``) chosen from
        the simulated film so that it comes closer to the target (``sprayplan.refine.tuning``). No effect
        without a target.
    min_dwell, max_dwell : float
        Bounds of those factors: the gun runs at between 1 / ``max_dwell`` and 1 / ``min_dwell`` times its
        planned speed (0.05 <= min_dwell <= 1 <= max_dwell <= 20).
    band : float
        Film errors up to this many tolerances cost nothing in the tuning (its dead band): larger favours
        the share in spec over uniformity; 0 <= band < 1.
    smoothing, iterations, loss, painted_fraction
        The least-squares fit's settings (``refine.tuning.TuningConfig``; ``refine.stage.tuning_settings``).
    touch_up_iterations : int
        Most evaluations of the tunings after each touch-up round, which start from the factors the round
        before found (1 on the added strokes) instead of 1 everywhere; at most ``iterations``.
    touch_up_rounds : int
        With speeds tuned: rounds of touch-up strokes, each aimed at a patch the tuned plan still leaves
        under-painted (a lip or flange that faces away from every stroke), run from the nearest station and
        tuned with the rest (``sprayplan.refine.touchup``); 0: none.
    touch_up_aim : bool
        Turn each touch-up to the tilt about its direction of travel that the film model favours; false: aim
        along the patch's normals.
    touch_up_stations : int
        At most this many gantry stations added for touch-ups no planned station reaches (a lip facing
        sideways or down, sprayed from beside the part), in all rounds together; 0: none.
    limit_rounds : int
        With timing: rounds of tuning the speeds again within the speeds the robot makes (each waypoint's
        timed speed becomes its speed's upper bound, then the plan is timed again; ``refine.limits``);
        0 (the default): the tuning ignores the robot's limits. Off by default because the arms' joint
        accelerations are not published (the UR models carry URScript's ``movej`` default, 80 deg/s^2): at
        those, the arm makes about a tenth of the spray speed on the demo roof, the tuned film comes out near
        three times the target, and the rounds take minutes. Turn them on with your arm's real limits
        (``[kinematics] robot_file``). With ``--cell`` the same rounds run on every robot's work after the flow
        fit (``cells.limits``), and the plan's own film is then the one at the timed speeds.
    """

    SECTION = "tuning"
    tune_speed: bool = True
    min_dwell: float = 0.5
    max_dwell: float = 2.0
    band: float = 0.3
    smoothing: float = 0.1
    iterations: int = 30
    loss: str = "huber"
    painted_fraction: float = 0.1
    touch_up_iterations: int = 20
    touch_up_rounds: int = 2
    touch_up_aim: bool = True
    touch_up_stations: int = 4
    limit_rounds: int = 0

    def _check(self):
        check_dwell_bounds(self.min_dwell, self.max_dwell, "tuning")
        _within(RefineConfig, "limit_rounds", self.limit_rounds, 0, 10)
        if not 0 <= self.band < 1:
            raise _fail(RefineConfig, "band", "a number in [0, 1)", self.band)
        _at_least(RefineConfig, "smoothing", self.smoothing, 0)
        _within(RefineConfig, "iterations", self.iterations, 1, 10_000)
        _within(RefineConfig, "touch_up_iterations", self.touch_up_iterations, 1, 10_000)
        _choice(RefineConfig, "loss", self.loss, ("huber", "linear"))
        _within(RefineConfig, "painted_fraction", self.painted_fraction, 0, 1)
        _within(RefineConfig, "touch_up_rounds", self.touch_up_rounds, 0, 10)
        _within(RefineConfig, "touch_up_stations", self.touch_up_stations, 0, 20)


#: The height search (``[collision] platform_search_mm``) tries at most this many raises above the seed's height.
MAX_HEIGHT_STEPS = 100


@dataclass(frozen=True)
class CollisionConfig(Section):
    """Collision checks and repairs of the plan (``[collision]``, ``sprayplan.collision``).

    Attributes
    ----------
    check : bool
        Check every waypoint and every motion of the plan against the part, the floor and the cell
        (``sprayplan plan --collisions``); the stations' heights are then chosen with the collision model too
        (``platform_search_mm``). Off by default for now: the check takes a minute or more on a car roof
        (docs/benchmarks.md, "The collision stage"), longer than the rest of the plan.
    repair : bool
        Free waypoints found in collision (another IK branch, a roll about the gun axis, a tilt within the
        axis tolerance, another gantry position) before flagging them.
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
    skip_floor_facing : bool
        Leave out of the painted surface what faces the floor (a body's underside): surface whose outward
        normal points more than ``floor_facing_deg`` below the horizontal. False for a part hung on a
        conveyor, painted from below too.
    floor_facing_deg : float
        0 to 90 degrees below the horizontal.
    skip_covered : bool
        Leave out of the painted surface what another face of the part covers: a face with a near-parallel
        face within ``covered_mm`` in front of it (a licence plate on a bumper, a handle on a door, the walls
        of a panel gap), which no gun reaches (``surface.region.covered_faces``).
    covered_mm : float
        How near the covering face must be, mm (more than 0.5).
    tilt_deg : float or None
        How far the tilt repair turns the gun axis; default 80 % of ``[kinematics] axis_tol_deg``.
    piece_tilt_deg : float
        A cell robot's run of waypoints still in collision after the repairs, which no untilted try frees, is
        tried with the gun tilted about its targets by half this and this, either way, sideways and then
        forward or back (``cells.repair.piece_tilts``), and painted as tilted; 0: no tilts. Tilts free more of
        the surface (on the BMW in ``line3`` the spray waypoints left out in collision fell from 1,766 to 697)
        and cost cycle time (the pieces start and stop; 1,459 to 1,619 s there): docs/benchmarks.md, "Session
        14". At most 60 degrees.
    platform_search_mm : float
        Before the kinematics, each station is tried at the seed's height raised by up to this much, in steps
        of ``platform_search_step_mm``, and goes to the lowest height at which about as many of its waypoints
        have a collision-free IK branch as at the best (``collision.heights``); 0: the seed's height. Only
        with ``check`` on and ``[stations] platform_z_mm`` unset.
    platform_search_step_mm : float
        The step of that search, at least 1 mm and at least a hundredth of ``platform_search_mm``.
    platform_raise_mm : float
        The gantry repair tries the station this much higher, then twice and three times as high.
    retract_mm : list of float
        A transfer in collision is first re-routed by retracting the gun along its axis at the end of the
        stroke before and approaching the stroke after along its axis by each of these lengths in turn
        (``collision.transfers``); empty: no retract routes.
    via_height_mm : float or None
        Then through two via poses with the gun tip this high above the part's top near the station, plus
        ``clearance_mm``; None: no via routes.
    detour : bool
        Then a joint-space detour: the straight joint move, then a seeded RRT-Connect search; for a cell
        robot, then out to a park and back (``cells.routes``, ``home``).
    detour_iterations : int
        The RRT-Connect search's iterations per transfer (each grows one tree once and tries to join the other):
        the cap on its cost, about 30 ms an iteration on the reach part under load (docs/benchmarks.md, "Transfers
        re-routed"). No search is made for a transfer whose end is in collision.
    cell_detour_iterations : int
        The same for a cell robot's transfers (``--cell ... --collisions``: an arm and its track, seven axes
        searched). Of the 48 transfers a BMW plan in ``line3`` left in collision at 200, 1000 iterations freed 17
        (420 s of search), 4000 freed 25 (1,522 s) (``bench/bench_detours.py``); but every transfer no search
        frees pays the whole search, and the SUV has hundreds (its collision step at 1000 had not ended after
        35 min, against 28 min at 200), so the default stays 200: raise it for a body with few.
    seed : int
        Random seed of the RRT-Connect search.
    cloud_radius_mm : float or None
        A point-cloud part's collision body is a ball of this radius about every point; None: from the cloud's
        spacing (``collision.spheres.cloud_radius_mm``).
    workers : int or None
        A cell plan's collision work (checks, repairs, routes, run-ups) runs one robot a process, this many at a
        time (``cells.each``; None: the cores; 1: one robot after the other in the planner's process). The
        results are the same either way.
    """

    SECTION = "collision"
    check: bool = False
    repair: bool = True
    clearance_mm: float = 30.0
    floor_offset_mm: float = 1.0
    floor_z_mm: float | None = None
    gun_radius_mm: float = 30.0
    motion_step_mm: float = 10.0
    skip_floor_facing: bool = True
    floor_facing_deg: float = 45.0
    skip_covered: bool = True
    covered_mm: float = 20.0
    tilt_deg: float | None = None
    piece_tilt_deg: float = 40.0
    platform_search_mm: float = 600.0
    platform_search_step_mm: float = 50.0
    platform_raise_mm: float = 150.0
    retract_mm: tuple = (50.0, 100.0, 200.0)
    via_height_mm: float | None = 100.0
    detour: bool = True
    detour_iterations: int = 200
    cell_detour_iterations: int = 200
    seed: int = 0
    cloud_radius_mm: float | None = None
    workers: int | None = None

    def _check(self):
        value = self.retract_mm
        if (
            isinstance(value, (str, bytes))
            or not hasattr(value, "__len__")
            or any(isinstance(v, (bool, str)) or not isinstance(v, (int, float)) for v in value)
            or not all(math.isfinite(v) and 0 < v <= MAX_COORDINATE_MM for v in value)
        ):
            raise _fail(CollisionConfig, "retract_mm", "a list of positive finite lengths", value)
        object.__setattr__(self, "retract_mm", tuple(float(v) for v in value))
        _at_least(CollisionConfig, "via_height_mm", self.via_height_mm, 0)
        _within(CollisionConfig, "detour_iterations", self.detour_iterations, 0, 100000)
        _within(CollisionConfig, "cell_detour_iterations", self.cell_detour_iterations, 0, 100000)
        _at_least(CollisionConfig, "seed", self.seed, 0)
        _at_least(CollisionConfig, "clearance_mm", self.clearance_mm, 0)
        _at_least(CollisionConfig, "floor_offset_mm", self.floor_offset_mm, 0)
        _at_least(CollisionConfig, "gun_radius_mm", self.gun_radius_mm, 0, strict=True)
        _at_least(CollisionConfig, "motion_step_mm", self.motion_step_mm, 0, strict=True)
        _within(CollisionConfig, "floor_facing_deg", self.floor_facing_deg, 0, 90)
        _within(CollisionConfig, "covered_mm", self.covered_mm, 0.5, MAX_COORDINATE_MM)
        _at_least(CollisionConfig, "tilt_deg", self.tilt_deg, 0)
        _within(CollisionConfig, "piece_tilt_deg", self.piece_tilt_deg, 0, 60)
        _within(CollisionConfig, "platform_search_mm", self.platform_search_mm, 0, MAX_COORDINATE_MM)
        _at_least(CollisionConfig, "platform_search_step_mm", self.platform_search_step_mm, 1)
        if self.platform_search_mm > MAX_HEIGHT_STEPS * self.platform_search_step_mm:
            raise _fail(
                CollisionConfig,
                "platform_search_step_mm",
                f"at least collision.platform_search_mm / {MAX_HEIGHT_STEPS} ({self.platform_search_mm / MAX_HEIGHT_STEPS:g})",
                self.platform_search_step_mm,
            )
        _at_least(CollisionConfig, "platform_raise_mm", self.platform_raise_mm, 0)
        _at_least(CollisionConfig, "cloud_radius_mm", self.cloud_radius_mm, 0, strict=True)
        _within(CollisionConfig, "workers", self.workers, 1, 256)
        if self.clearance_mm > 0 and self.motion_step_mm > 2 * self.clearance_mm:
            raise _fail(
                CollisionConfig,
                "motion_step_mm",
                f"at most twice collision.clearance_mm ({2 * self.clearance_mm:g})",
                self.motion_step_mm,
            )


@dataclass(frozen=True)
class TimingConfig(Section):
    """Timing within the joints' limits (``[timing]``, ``sprayplan.timing``): each stroke time-optimal along its
    joint path, transfers and station moves time-optimal from point to point.

    Attributes
    ----------
    enabled : bool
        Time the plan (time stamps, the real cycle time, the film at the speeds the robot makes); false: the
        cycle time is length over speed only.
    arm_max_velocity_deg_s, arm_max_acceleration_deg_s2 : list of 6 float or None
        The arm's joint limits; None: the robot model's (UR5 / UR5e: 180 deg/s, 80.2 deg/s^2; see
        ``robots.model``).
    gantry_max_velocity_mm_s : list of 3 float or None
        The gantry's x, y, z axis speeds; None: ``[motion] platform_speed_mm_s`` on each.
    gantry_max_acceleration_mm_s2 : list of 3 float
        The gantry's x, y, z axis accelerations (the seed gives none: an assumption, 500 mm/s^2).
    track_max_acceleration_mm_s2 : float
        A cell robot's track acceleration (``sprayplan plan --cell``; the track's speed is the cell file's;
        no maker's figure: an assumption, 500 mm/s^2 as the gantry's axes). In a cell the arm settings above
        apply to every robot's arm of their number of axes (``cells.timing``).
    check_steps : int
        The time-parameterised strokes are checked against every limit at this many points per grid interval
        (toppra holds the limits at its grid points only), and refined where they do not hold.
    max_rounds : int
        Most grid refinements before the stroke's time is stretched uniformly (which always holds). On the
        demo roof's first station 2 took a fifth of the time of 6 for a 0.2 % longer cycle.
    joint_jump_deg : float
        A spray stroke is not followed across two waypoints where an arm joint moves by more than this (an IK
        branch change, an SQP solution far from its neighbours): the arm makes a joint move there instead.
    film_at_timed_speeds : bool
        Predict the film at the timed speeds (the speeds the robot makes under its limits) instead of the
        plan's own (tuned) speeds. Off by default: with the default (conservative) accelerations the arm makes
        a small share of the planned spray speed, so a film target comes out far above spec when timed, even
        with the speeds tuned within the limits (``[tuning] limit_rounds``; docs/benchmarks.md).
    fit_flow : bool
        A cell plan (``--cell``) with a film target and tuned speeds: the paint's flow and the gun speed scaled
        down together to what the robots make (``cells.fit``: of the shares 1, 0.7, 0.5, 0.35 and 0.25, the one
        with the most surface in spec at the timed speeds whose timed cycle is within ``fit_cycle_budget``
        times the cycle at the flow as set; every share tried is in the report's ``flow_fit``). The plan's
        predicted film does not change; the film the robots leave at their timed speeds comes nearer to it and
        the cycle grows. False: the flow as set. Gantry plans keep the flow as set.
    fit_cycle_budget : float
        The longest timed cycle the flow fit may take, as a multiple of the timed cycle at the flow as set
        (1.5: half as long again; 1: the flow as set).
    run_up_mm : float
        A cell plan's six-axis arms (``--cell``): every spray stretch begins with a run-up of this length, spray
        off, straight back along its first segment, and ends with a run-out as long along its last, so that the
        gun passes the stretch's first and last waypoints at speed instead of starting and stopping there
        (``cells.runups``: shortened to a half or a quarter, or left out, where the arm cannot make it or it
        would collide). The timing, the schedule and the programs all make them. 0: none (every stretch from
        rest to rest at its ends). Gantry plans make none. On the BMW body in ``line3`` (at 163 mm/s) 10 mm
        gave nearly all of the gain in the film at the timed speeds for the least cycle time (71.5 -> 74.9 %
        in spec, 1,699 -> 1,772 s; 50 mm: 75.0 % at 1,961 s; docs/benchmarks.md, "Session 24"); arms slower
        to accelerate than the assumed ones need longer.
    """

    SECTION = "timing"
    enabled: bool = True
    arm_max_velocity_deg_s: tuple | None = None
    arm_max_acceleration_deg_s2: tuple | None = None
    gantry_max_velocity_mm_s: tuple | None = None
    gantry_max_acceleration_mm_s2: tuple = (500.0, 500.0, 500.0)
    track_max_acceleration_mm_s2: float = 500.0
    check_steps: int = 4
    max_rounds: int = 2
    joint_jump_deg: float = 30.0
    film_at_timed_speeds: bool = False
    fit_flow: bool = True
    fit_cycle_budget: float = 1.5
    run_up_mm: float = 10.0

    def _check(self):
        from sprayplan.robots.model import check_rate_limits

        for name, n in (
            ("arm_max_velocity_deg_s", 6),
            ("arm_max_acceleration_deg_s2", 6),
            ("gantry_max_velocity_mm_s", 3),
            ("gantry_max_acceleration_mm_s2", 3),
        ):
            value = getattr(self, name)
            if value is None:
                continue
            if (
                isinstance(value, (str, bytes))
                or not hasattr(value, "__len__")
                or any(isinstance(v, (bool, str)) for v in value)
            ):
                raise _fail(TimingConfig, name, f"{n} positive finite numbers", value)
            try:
                checked = check_rate_limits(value, f"{TimingConfig.SECTION}.{name}", n)
            except ConfigError as exc:
                raise ConfigError(str(exc).replace(" (one per joint)", "")) from None
            object.__setattr__(self, name, tuple(float(v) for v in checked))
        _within(TimingConfig, "track_max_acceleration_mm_s2", self.track_max_acceleration_mm_s2, 1e-6, 1e9)
        _within(TimingConfig, "check_steps", self.check_steps, 1, 100)
        _within(TimingConfig, "max_rounds", self.max_rounds, 0, 100)
        _within(TimingConfig, "joint_jump_deg", self.joint_jump_deg, 1e-6, 360.0)
        _within(TimingConfig, "fit_cycle_budget", self.fit_cycle_budget, 1.0, 100.0)
        _within(TimingConfig, "run_up_mm", self.run_up_mm, 0.0, 1000.0)


@dataclass(frozen=True)
class OutputConfig(Section):
    """What the main job writes besides plan.json and waypoints.csv (``[output]``).

    Attributes
    ----------
    simulate : bool
        Predict the film (thickness.ply, thickness.csv, coating.json); always done with a film target.
    samples : int or None
        Also report the film at this many random points (seed 003: 420).
    viewer : bool
        Write plan.html, the 3D viewer of the plan (``sprayplan.view.html``).
    report : bool
        Write report/, the picture report (PNG images and report.md, ``sprayplan.view.report``).
    """

    SECTION = "output"
    simulate: bool = False
    samples: int | None = None
    viewer: bool = True
    report: bool = True

    def _check(self):
        _at_least(OutputConfig, "samples", self.samples, 1)
        _at_most(OutputConfig, "samples", self.samples, MAX_REPORT_SAMPLES)


#: The robot program formats ``[export] programs`` and ``sprayplan export --format`` take.
PROGRAM_FORMATS = ("urscript", "rapid", "krl")

_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*\Z")
#: RAPID's reserved words that a data name must not be (the ones a name could plausibly collide with).
_RAPID_RESERVED = {
    "AND", "BACKWARD", "CASE", "CONNECT", "CONST", "DEFAULT", "DIV", "DO", "ELSE", "ELSEIF", "ENDFOR", "ENDFUNC",
    "ENDIF", "ENDMODULE", "ENDPROC", "ENDRECORD", "ENDTEST", "ENDTRAP", "ENDWHILE", "ERROR", "EXIT", "FALSE",
    "FOR", "FROM", "FUNC", "GOTO", "IF", "INOUT", "LOCAL", "MOD", "MODULE", "NOSTEPIN", "NOT", "NOVIEW", "OR",
    "PERS", "PROC", "RAISE", "READONLY", "RECORD", "RETRY", "RETURN", "STEP", "SYSMODULE", "TEST", "THEN", "TO",
    "TRAP", "TRUE", "TRYNEXT", "UNDO", "VAR", "VIEWONLY", "WHILE", "WITH", "XOR",
}  # fmt: skip


@dataclass(frozen=True)
class ExportConfig(Section):
    """Robot programs (``[export]``, ``sprayplan export``, ``sprayplan plan --program``; docs/programs.md).

    Attributes
    ----------
    programs : tuple of str
        Formats the main job writes into OUT/programs/<format>/ as its last stage (``urscript``, ``rapid``,
        ``krl``); empty: none.
    strict : bool
        A spray waypoint the plan marks unreachable is an error (nothing written) instead of a waypoint left
        out with the gun off.
    name : str
        Base name of the programs (module, procedure and file names): a letter, then letters, digits or
        underscores, at most 16 characters.
    approach_mm : float
        Retract after and approach before every spray run, along the gun axis (> 0).
    approach_speed_mm_s : float
        TCP speed of the approach and retract moves; slower where the gun's opening lead must fit on the
        approach (``lead_on_s`` times the speed at most ``approach_mm``).
    joint_speed_deg_s, joint_acceleration_deg_s2 : float
        Joint moves between runs: the joints' speed and acceleration (URScript ``movej`` v, a; RAPID
        ``MoveAbsJ`` reorientation speed).
    linear_acceleration_mm_s2 : float
        URScript ``movel``/``movep`` acceleration.
    transfer_speed_mm_s : float
        RAPID ``MoveAbsJ`` TCP speed.
    gantry_speed_mm_s : float
        Speed of the gantry's axes in RAPID's joint moves (``v_leax`` of ``MoveAbsJ``); KRL's ``PTP`` moves
        every axis, the gantry's too, at ``ptp_velocity_pct``.
    ptp_velocity_pct : float
        KRL ``PTP`` speed, percent of each axis's maximum (0 < pct <= 100).
    lead_on_s, lead_off_s : float
        The gun's opening and closing delay: the gun signal is switched this long before the gun must be open
        (at a run's first waypoint) or closed (at its last), at the program's speeds (0 to 2 s).
    blend_mm : float
        Largest blend radius (URScript ``r``, RAPID zone, KRL ``C_DIS``) between the moves of a run (>= 0).
    blend_share : float
        A blend radius is at most this share of the shorter neighbouring segment (0 < share <= 0.5; 0.4 keeps
        neighbouring blends apart: "Blend radius too small" otherwise).
    tool_mass_kg : float
        The gun's mass in the RAPID tool data (> 0; the controller refuses a tool without a load).
    ur_gun_output, ur_ready_input, ur_done_output : int
        URScript standard digital I/O (0 to 7): the gun; the cell PLC's "gantry in position" (each station
        script waits for it before it moves); the "station done" output the script sets at its end.
    ur_max_moves : int
        Most moves in one URScript file (a station's script is split into parts beyond it; >= 20).
    ur_gantry_offset_mm : float
        URScript holds the gantry at its station: a spray waypoint where the plan (its SQP fallback) moves the
        gantry farther than this from the station is left out, nearer ones are sprayed with the arm's joints
        from the station (the TCP then that much off the plan's pose; 0 to 200 mm).
    rapid_gun_signal, rapid_tool, rapid_wobj : str
        RAPID names of the gun's digital output, the tool data and the work object (identifiers, at most 32
        characters, not a reserved word).
    rapid_max_lines : int
        Most lines in one RAPID module (>= 50); the main module calls the modules in order.
    rapid_paint : bool
        Write RobotWare Paint's ``PaintL`` with ``SetBrush`` brush events instead of ``TriggL``/``TriggIO``
        (the paint system then applies the gun's delays from its own tables).
    rapid_brush_on, rapid_brush_off : int
        With ``rapid_paint``: the brush numbers (0 to 255, different) that open and close the gun.
    krl_gun_output : int
        KRL ``$OUT`` number of the gun (1 to 4096).
    krl_tool, krl_base : int
        KRL ``TOOL_DATA`` (1 to 16) and ``BASE_DATA`` (1 to 32) numbers the program sets and uses.
    krl_max_moves : int
        Most moves in one KRL subprogram (>= 20).
    """

    SECTION = "export"
    programs: tuple = ()
    strict: bool = False
    name: str = "sprayplan"
    approach_mm: float = 50.0
    approach_speed_mm_s: float = 250.0
    joint_speed_deg_s: float = 60.0
    joint_acceleration_deg_s2: float = 80.0
    linear_acceleration_mm_s2: float = 1200.0
    transfer_speed_mm_s: float = 500.0
    gantry_speed_mm_s: float = 250.0
    ptp_velocity_pct: float = 30.0
    lead_on_s: float = 0.05
    lead_off_s: float = 0.03
    blend_mm: float = 10.0
    blend_share: float = 0.4
    tool_mass_kg: float = 1.0
    ur_gun_output: int = 0
    ur_ready_input: int = 0
    ur_done_output: int = 1
    ur_max_moves: int = 2000
    ur_gantry_offset_mm: float = 2.0
    rapid_gun_signal: str = "doGun"
    rapid_tool: str = "tSprayGun"
    rapid_wobj: str = "wPart"
    rapid_max_lines: int = 5000
    rapid_paint: bool = False
    rapid_brush_on: int = 1
    rapid_brush_off: int = 0
    krl_gun_output: int = 1
    krl_tool: int = 1
    krl_base: int = 1
    krl_max_moves: int = 1000

    def _check(self):
        formats = self.programs
        if isinstance(formats, str):
            formats = (formats,)
        if not isinstance(formats, (tuple, list)) or not all(isinstance(f, str) for f in formats):
            raise _fail(ExportConfig, "programs", "a list of formats (" + ", ".join(PROGRAM_FORMATS) + ")", formats)
        for value in formats:
            _choice(ExportConfig, "programs", value, PROGRAM_FORMATS)
        if len(set(formats)) != len(formats):
            raise _fail(ExportConfig, "programs", "a list of different formats", list(formats))
        object.__setattr__(self, "programs", tuple(formats))
        if not (_NAME.match(self.name) and len(self.name) <= 16):
            raise _fail(ExportConfig, "name", "a letter, then letters, digits or _, at most 16 characters", self.name)
        _within(ExportConfig, "approach_mm", self.approach_mm, MIN_STEP_MM, 1000.0)
        for key in (
            "approach_speed_mm_s",
            "joint_speed_deg_s",
            "joint_acceleration_deg_s2",
            "linear_acceleration_mm_s2",
            "transfer_speed_mm_s",
            "gantry_speed_mm_s",
            "tool_mass_kg",
        ):
            _at_least(ExportConfig, key, getattr(self, key), 0, strict=True)
        if not 0 < self.ptp_velocity_pct <= 100:
            raise _fail(ExportConfig, "ptp_velocity_pct", "a number > 0 and at most 100", self.ptp_velocity_pct)
        for key in ("lead_on_s", "lead_off_s"):
            _within(ExportConfig, key, getattr(self, key), 0.0, 2.0)
        _at_least(ExportConfig, "blend_mm", self.blend_mm, 0)
        if not 0 < self.blend_share <= 0.5:
            raise _fail(ExportConfig, "blend_share", "a number > 0 and at most 0.5", self.blend_share)
        for key in ("ur_gun_output", "ur_ready_input", "ur_done_output"):
            _within(ExportConfig, key, getattr(self, key), 0, 7)
        if self.ur_gun_output == self.ur_done_output:
            raise _fail(ExportConfig, "ur_done_output", "another output than ur_gun_output", self.ur_done_output)
        for key in ("ur_max_moves", "krl_max_moves"):
            _within(ExportConfig, key, getattr(self, key), 20, 1_000_000)
        _within(ExportConfig, "rapid_max_lines", self.rapid_max_lines, 50, 1_000_000)
        _within(ExportConfig, "ur_gantry_offset_mm", self.ur_gantry_offset_mm, 0.0, 200.0)
        names = {}
        for key in ("rapid_gun_signal", "rapid_tool", "rapid_wobj"):
            value = getattr(self, key)
            if not (_NAME.match(value) and len(value) <= 32) or value.upper() in _RAPID_RESERVED:
                raise _fail(ExportConfig, key, "a RAPID name (a letter, then letters, digits or _, at most 32)", value)
            if value.lower() in names:
                raise _fail(ExportConfig, key, f"another name than {names[value.lower()]}", value)
            names[value.lower()] = key
        for key in ("rapid_brush_on", "rapid_brush_off"):
            _within(ExportConfig, key, getattr(self, key), 0, 255)
        if self.rapid_brush_on == self.rapid_brush_off:
            raise _fail(ExportConfig, "rapid_brush_off", "another brush than rapid_brush_on", self.rapid_brush_off)
        _within(ExportConfig, "krl_gun_output", self.krl_gun_output, 1, 4096)
        _within(ExportConfig, "krl_tool", self.krl_tool, 1, 16)
        _within(ExportConfig, "krl_base", self.krl_base, 1, 32)


@dataclass(frozen=True)
class JobConfig:
    """Every setting of the main job, one section per stage (the TOML file's tables).

    Attributes
    ----------
    mode : {"paths", "points"}
        ``paths``: slicing strokes (the default); ``points``: the seed's target points visited in a tour.
    load, targets, paths, stations, ordering, kinematics, motion, coating, tuning, collision, timing, output,
    export
        One section each (``[load]``, ``[targets]``, ...).
    """

    mode: str = "paths"
    load: LoadConfig = LoadConfig()
    targets: TargetsConfig = TargetsConfig()
    paths: PathConfig = PathConfig()
    stations: StationsConfig = StationsConfig()
    ordering: OrderingConfig = OrderingConfig()
    kinematics: KinematicsConfig = KinematicsConfig()
    motion: MotionConfig = MotionConfig()
    coating: FilmConfig = FilmConfig()
    tuning: RefineConfig = RefineConfig()
    collision: CollisionConfig = CollisionConfig()
    timing: TimingConfig = TimingConfig()
    output: OutputConfig = OutputConfig()
    export: ExportConfig = ExportConfig()

    def __post_init__(self):
        if self.mode not in MODES:
            raise ConfigError(f"mode must be one of {', '.join(MODES)}, got {self.mode!r}")
        for name, cls in SECTIONS.items():
            if not isinstance(getattr(self, name), cls):
                raise ConfigError(f"JobConfig.{name} must be a {cls.__name__}, got {getattr(self, name)!r}")

    @property
    def film_target(self) -> bool:
        """True when the job has a dry-film target (``[coating] thickness_um``)."""
        return self.coating.thickness_um is not None

    def replace(self, **sections) -> JobConfig:
        """The job with some settings changed: ``job.replace(coating={"thickness_um": 50}, mode="points")``.

        A section given as a dict changes only those keys of it; a section object replaces it whole.
        """
        changes = {}
        for name, value in sections.items():
            if name == "mode":
                changes[name] = value
            elif name not in SECTIONS:
                raise ConfigError(f"unknown section {name!r}; known: mode, {', '.join(SECTIONS)}")
            elif isinstance(value, dict):
                changes[name] = config_from_dict(SECTIONS[name], {**_asdict(getattr(self, name)), **value})
            else:
                changes[name] = value
        return dataclasses.replace(self, **changes)


SECTIONS = {
    "load": LoadConfig,
    "targets": TargetsConfig,
    "paths": PathConfig,
    "stations": StationsConfig,
    "ordering": OrderingConfig,
    "kinematics": KinematicsConfig,
    "motion": MotionConfig,
    "coating": FilmConfig,
    "tuning": RefineConfig,
    "collision": CollisionConfig,
    "timing": TimingConfig,
    "output": OutputConfig,
    "export": ExportConfig,
}

#: Where each key of the old ``[plan]`` table (before 0.2) lives now, for the error that points a user there.
_MOVED = {
    "mode": "the top level (mode = ...)",
    "tour": "[ordering]",
    "robot": "[kinematics]",
    "tool": "[kinematics]",
    "position_tol_mm": "[kinematics]",
    "axis_tol_deg": "[kinematics]",
    "k_d": "[kinematics]",
    "gun_speed_mm_s": "[motion]",
    "transfer_speed_mm_s": "[motion]",
    "platform_speed_mm_s": "[motion]",
    "speed_along": "[motion]",
    "max_speed_ratio": "[motion]",
    "home_mm": "[stations]",
    "platform_z_mm": "[stations]",
    "process": "[coating]",
    "thickness_um": "[coating]",
    "tolerance_um": "[coating]",
    "tune_speed": "[tuning]",
    "min_dwell": "[tuning]",
    "max_dwell": "[tuning]",
    "tune_band": "[tuning] band",
    "touch_up_rounds": "[tuning]",
    "touch_up_aim": "[tuning]",
    "touch_up_stations": "[tuning]",
    "seed": "[stations] and [ordering]",
}


def _asdict(section) -> dict:
    return {f.name: getattr(section, f.name) for f in dataclasses.fields(section)}


def job_to_dict(job: JobConfig) -> dict:
    """The job's settings as plain data (tuples as lists), read back by :func:`job_from_dict`."""

    def plain(value):
        return list(value) if isinstance(value, tuple) else value

    out: dict = {"mode": job.mode}
    for name in SECTIONS:
        out[name] = {k: plain(v) for k, v in _asdict(getattr(job, name)).items()}
    return out


def job_from_dict(data: dict) -> JobConfig:
    """A JobConfig from plain data (a TOML file's tables, or plan.json's ``settings``).

    Raises
    ------
    ConfigError
        An unknown table or key, or a bad value; the message names the table and key.
    """
    if not isinstance(data, dict):
        raise ConfigError(f"settings must be a table, got {type(data).__name__}")
    if "plan" in data:
        table = data["plan"] if isinstance(data["plan"], dict) else {}
        where = "; ".join(f"{k} -> {_MOVED[k]}" for k in table if k in _MOVED) or "see examples/process.toml"
        raise ConfigError(f"the [plan] table was split into sections: {where}")
    unknown = sorted(set(data) - set(SECTIONS) - {"mode"})
    if unknown:
        raise ConfigError(f"unknown table(s) {', '.join(unknown)}; known: mode, {', '.join(SECTIONS)}")
    parts: dict = {}
    for key, cls in SECTIONS.items():
        table = data.get(key, {})
        if not isinstance(table, dict):
            raise ConfigError(f"[{key}] must be a table")
        table = dict(table)
        for name in ("direction", "streamline_deg", "home_mm", "programs"):
            if isinstance(table.get(name), list):
                table[name] = tuple(table[name])
        try:
            parts[key] = config_from_dict(cls, table)
        except TypeError as exc:
            raise ConfigError(f"[{key}]: {exc}") from None
    return JobConfig(mode=data.get("mode", "paths"), **parts)


def job_from_toml(path) -> JobConfig:
    """Read a process TOML file (``mode`` and the tables ``[load]``, ``[targets]``, ``[paths]``, ...).

    Raises
    ------
    PartFileError
        A missing or broken file, an unknown table or key, or a bad value; the message names the file.
    """
    import tomllib

    from sprayplan.checks import check_input_file

    name = check_input_file(path)  # a folder or a named pipe is refused before it is opened
    try:
        with open(path, "rb") as handle:
            data = tomllib.load(handle)
    except FileNotFoundError:
        raise _PartFileError(name, "no such file") from None
    except IsADirectoryError:
        raise _PartFileError(name, "is a folder, not a TOML file") from None
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise _PartFileError(name, f"not a readable TOML file ({exc})") from None
    try:
        return job_from_dict(data)
    except ConfigError as exc:
        raise _PartFileError(name, str(exc)) from None
