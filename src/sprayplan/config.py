"""Typed configuration of each stage, with every default in one place.

Each stage takes one frozen dataclass; :func:`config_from_dict` builds one from a TOML table (keys as the field
names, units in the names), rejecting unknown keys so that a typo does not pass silently.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from sprayplan.errors import ConfigError

#: Smallest time factor of a waypoint (``Stroke.dwell``) the speed tuning may choose, and 1 / this the largest:
#: a gun 20 times faster or slower than planned is a different plan, not a correction.
MIN_DWELL = 0.05

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


@dataclass(frozen=True)
class PathConfig:
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
    rim_mm: float | None = None
    edge_passes: str | int = "auto"

    def __post_init__(self):
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
            object.__setattr__(self, "edge_passes", int(self.edge_passes))
        if self.cloud_normals not in ("triangles", "plane"):
            raise ConfigError(f"cloud_normals must be triangles or plane, got {self.cloud_normals!r}")
        if isinstance(self.direction, str):
            if self.direction not in ("auto", "x", "y", "z"):
                raise ConfigError(f"direction must be auto, x, y, z or a vector, got {self.direction!r}")
        else:
            vector = tuple(float(v) for v in self.direction)
            if len(vector) != 3 or not all(math.isfinite(v) for v in vector) or not any(vector):
                raise ConfigError(f"direction vector must be three finite numbers, not all 0, got {self.direction!r}")
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
        if self.layers is not None and self.spacing_mm is not None:
            raise ConfigError("give either layers or spacing_mm, not both")
        for name in ("spacing_mm", "spray_radius_mm", "step_mm", "split_gap_mm", "slab_mm", "cloud_smooth_mm"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value > 0):
                raise ConfigError(f"{name} must be a positive number, got {value}")
        if self.cloud_normal_smooth_mm is not None and not (
            math.isfinite(self.cloud_normal_smooth_mm) and self.cloud_normal_smooth_mm >= 0
        ):
            raise ConfigError(f"cloud_normal_smooth_mm must be a number >= 0, got {self.cloud_normal_smooth_mm}")
        if self.rim_mm is not None and not (math.isfinite(self.rim_mm) and self.rim_mm >= 0):
            raise ConfigError(f"rim_mm must be a number >= 0, got {self.rim_mm}")
        if self.edge_margin_mm is not None and not (math.isfinite(self.edge_margin_mm) and self.edge_margin_mm >= 0):
            raise ConfigError(f"edge_margin_mm must be a number >= 0, got {self.edge_margin_mm}")
        if not (math.isfinite(self.standoff_mm) and self.standoff_mm >= 0):
            raise ConfigError(f"standoff_mm must be a number >= 0, got {self.standoff_mm}")
        if not 0.0 <= self.overlap < 1.0:
            raise ConfigError(f"overlap must be in [0, 1), got {self.overlap}")
        if self.streamline_deg is not None:
            lo, hi = (float(v) for v in self.streamline_deg)
            if not 90.0 <= lo <= hi <= 180.0:
                raise ConfigError("streamline_deg must be [alpha_min, alpha_max] with 90 <= min <= max <= 180")
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
class PlanConfig:
    """The main job, ``sprayplan plan`` (seed 000 sections 5-6 around the paths of seed 003).

    Attributes
    ----------
    mode : {"paths", "points"}
        ``paths``: slicing strokes (the default); ``points``: the seed's target points visited in a tour.
    tour : {"auto", "ga", "exact", "keep"}
        Ordering inside a station: of the strokes (``keep``: zig-zag order as sliced) or, in points mode, of
        the targets (``ga``: the seed's genetic algorithm). ``auto`` is a deterministic descent (nearest
        neighbour, 2-opt, Or-opt), so that a plan repeats exactly on any machine.
    robot : str
        ``gantry-ur5`` (seed 000's nine axes).
    tool : str
        Gun preset (``wa101``).
    gun_speed_mm_s, transfer_speed_mm_s, platform_speed_mm_s : float
        For the cycle time: spraying, spray-off moves of the arm, and the gantry.
    speed_along : {"surface", "tcp"}
        What moves at ``gun_speed_mm_s`` while spraying: the paint's contact point on the surface (the gun
        tip then speeds up over convex bends and slows down in concave ones; plan.json gives the tip's speed
        per waypoint), or the gun tip itself (one speed per stroke). See ``sprayplan.paths.speed``.
    max_speed_ratio : float
        With ``surface``: the gun tip's speed stays within [v / ratio, v ratio].
    home_mm : tuple of 3 float
        Where the gantry starts and ends (the seed's "zero").
    platform_z_mm : float or None
        Gantry height; None: the part's targets at the middle of the working cylinder.
    position_tol_mm, axis_tol_deg : float
        Allowed errors of the SQP fallback (eqs. 21-22; seed: 5 mm, 5 degrees).
    k_d : float
        Weight of gantry travel in eq. 20, rad^2/mm^2 (0.1: 3.2 mm of travel costs as much as 1 rad).
    process : str
        Spray process preset or TOML file (``seed000_circle``, ``seed000_flat``, ``bell003``): the pattern,
        flow, solids and transfer efficiency used to predict the film.
    thickness_um : float or None
        A dry-film target: when set, the stroke spacing and the gun speed are chosen to meet it (the spacing
        that makes the film across parallel strokes flattest, the speed that puts its mean on target), in
        place of ``[paths] spacing_mm`` and ``gun_speed_mm_s``.
    tolerance_um : float
        The spec is ``thickness_um +- tolerance_um`` (default 5, seed 003's); without a target the film is
        judged against seed 003's 50 +- 5 um.
    tune_speed : bool
        With a target: after planning, give every waypoint a time factor (``Stroke.dwell``) chosen from the
        simulated film so that it comes closer to the target (``sprayplan.coating.tuning``). No effect without
        a target.
    min_dwell, max_dwell : float
        Bounds of those factors: the gun runs at between 1 / ``max_dwell`` and 1 / ``min_dwell`` times its
        planned speed (0.05 <= min_dwell <= 1 <= max_dwell <= 20).
    touch_up_rounds : int
        With speeds tuned: rounds of touch-up strokes, each aimed at a patch the tuned plan still leaves
        under-painted (a lip or flange that faces away from every stroke), run from the nearest station and
        tuned with the rest (``sprayplan.coating.touchup``); 0: none.
    tune_band : float
        Film errors up to this many tolerances cost nothing in the tuning (its dead band,
        ``coating.TuningConfig.band``): larger favours the share in spec over uniformity; 0 <= tune_band < 1.
    touch_up_aim : bool
        Turn each touch-up to the tilt about its direction of travel that the film model favours
        (``coating.touchup.aim_touch_ups``); false: aim along the patch's normals.
    touch_up_stations : int
        At most this many gantry stations added for touch-ups no planned station reaches (a lip facing
        sideways or down, sprayed from beside the part), in all rounds together; 0: none.
    seed : int
    """

    mode: str = "paths"
    tour: str = "auto"
    robot: str = "gantry-ur5"
    tool: str = "wa101"
    gun_speed_mm_s: float = 400.0
    transfer_speed_mm_s: float = 1000.0
    platform_speed_mm_s: float = 250.0
    speed_along: str = "surface"
    max_speed_ratio: float = 3.0
    home_mm: tuple = (0.0, 0.0, 0.0)
    platform_z_mm: float | None = None
    position_tol_mm: float = 5.0
    axis_tol_deg: float = 5.0
    k_d: float = 0.1
    process: str = "seed000_circle"
    thickness_um: float | None = None
    tolerance_um: float = 5.0
    tune_speed: bool = True
    min_dwell: float = 0.5
    max_dwell: float = 2.0
    tune_band: float = 0.3
    touch_up_rounds: int = 2
    touch_up_aim: bool = True
    touch_up_stations: int = 4
    seed: int = 0

    def __post_init__(self):
        if self.mode not in ("paths", "points"):
            raise ConfigError(f"mode must be paths or points, got {self.mode!r}")
        if self.tour not in ("auto", "ga", "exact", "keep"):
            raise ConfigError(f"tour must be auto, ga, exact or keep, got {self.tour!r}")
        if self.robot != "gantry-ur5":
            raise ConfigError(f"robot must be gantry-ur5 for the plan, got {self.robot!r}")
        for name in ("gun_speed_mm_s", "transfer_speed_mm_s", "platform_speed_mm_s", "position_tol_mm", "axis_tol_deg"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"{name} must be a positive number, got {value}")
        if self.speed_along not in ("surface", "tcp"):
            raise ConfigError(f"speed_along must be surface or tcp, got {self.speed_along!r}")
        if not (math.isfinite(self.max_speed_ratio) and self.max_speed_ratio >= 1.0):
            raise ConfigError(f"max_speed_ratio must be a number >= 1, got {self.max_speed_ratio}")
        if self.thickness_um is not None and not (math.isfinite(self.thickness_um) and self.thickness_um > 0):
            raise ConfigError(f"thickness_um must be a positive number, got {self.thickness_um}")
        if not (math.isfinite(self.tolerance_um) and self.tolerance_um >= 0):
            raise ConfigError(f"tolerance_um must be a number >= 0, got {self.tolerance_um}")
        if not (MIN_DWELL <= self.min_dwell <= 1.0 <= self.max_dwell <= 1.0 / MIN_DWELL):
            raise ConfigError(
                f"need {MIN_DWELL} <= min_dwell <= 1 <= max_dwell <= {1 / MIN_DWELL:g}, got {self.min_dwell}, "
                f"{self.max_dwell}"
            )
        if not isinstance(self.tune_speed, bool):
            raise ConfigError(f"tune_speed must be true or false, got {self.tune_speed!r}")
        object.__setattr__(self, "tune_speed", bool(self.tune_speed))
        if not (isinstance(self.touch_up_rounds, int) and 0 <= self.touch_up_rounds <= 10):
            raise ConfigError(f"touch_up_rounds must be an integer from 0 to 10, got {self.touch_up_rounds!r}")
        if isinstance(self.tune_band, bool) or not (
            isinstance(self.tune_band, (int, float)) and math.isfinite(self.tune_band) and 0 <= self.tune_band < 1
        ):
            raise ConfigError(f"tune_band must be a number in [0, 1), got {self.tune_band!r}")
        if not isinstance(self.touch_up_aim, bool):
            raise ConfigError(f"touch_up_aim must be true or false, got {self.touch_up_aim!r}")
        if isinstance(self.touch_up_stations, bool) or not (
            isinstance(self.touch_up_stations, int) and 0 <= self.touch_up_stations <= 20
        ):
            raise ConfigError(f"touch_up_stations must be an integer from 0 to 20, got {self.touch_up_stations!r}")
        home = tuple(float(v) for v in self.home_mm)
        if len(home) != 3 or not all(math.isfinite(v) for v in home):
            raise ConfigError("home_mm must be three numbers")
        object.__setattr__(self, "home_mm", home)


@dataclass(frozen=True)
class JobConfig:
    """Every setting of ``sprayplan plan``, one section per stage (the TOML file's tables)."""

    load: LoadConfig = LoadConfig()
    targets: TargetsConfig = TargetsConfig()
    paths: PathConfig = PathConfig()
    plan: PlanConfig = PlanConfig()


def job_from_toml(path) -> JobConfig:
    """Read a process TOML file (tables ``[load]``, ``[targets]``, ``[paths]``, ``[plan]``).

    Raises
    ------
    PartFileError
        A missing or broken file, an unknown table or key, or a bad value; the message names the file.
    """
    import os
    import tomllib

    from sprayplan.errors import PartFileError

    name = os.fspath(path)
    try:
        with open(path, "rb") as handle:
            data = tomllib.load(handle)
    except FileNotFoundError:
        raise PartFileError(name, "no such file") from None
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise PartFileError(name, f"not a readable TOML file ({exc})") from None
    tables = {"load": LoadConfig, "targets": TargetsConfig, "paths": PathConfig, "plan": PlanConfig}
    unknown = sorted(set(data) - set(tables))
    if unknown:
        raise PartFileError(name, f"unknown table(s) {', '.join(unknown)}; known: {', '.join(tables)}")
    parts = {}
    for key, cls in tables.items():
        table = data.get(key, {})
        if not isinstance(table, dict):
            raise PartFileError(name, f"[{key}] must be a table")
        try:
            parts[key] = config_from_dict(cls, table)
        except (ConfigError, TypeError) as exc:
            raise PartFileError(name, f"[{key}]: {exc}") from None
    return JobConfig(**parts)
