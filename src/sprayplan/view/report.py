"""The picture report of a plan (``OUT/report/``): PNG images drawn with matplotlib's Agg backend (no display
needed) and ``report.md``, which holds the summary tables and shows the images, so that a report can be
attached to a job and read without any tool.

Images (``size_px`` each, default 1200 x 900):

- ``film_top.png`` and two sides (``film_<side>.png``, the two of +x, -x, +y, -y and below that face the most
  painted area): the film on the part, in an orthographic view, on the viewer's colour scale
  (``view.colours``); the back of a surface (facing away) is drawn light grey;
- ``film_histogram.png``: the film over the painted area, area-weighted, the spec band shaded;
- ``strokes_stopNN.png``: each station's strokes from above, numbered in the order they are run;
- ``gantry_tour.png``: the stations, their working circles and the gantry's tour, from above;
- ``measuring_points.png`` (when the plan asked for seed 003's measuring points): the film at each point, as
  the seed's figure 17.

Triangles are drawn back to front (painter's order by their centres' depth) after the thinning of
``view.decimate``.
"""

from __future__ import annotations

import itertools
import logging
import os
from dataclasses import dataclass, replace

import numpy as np
from matplotlib.artist import Artist, allow_rasterization

from sprayplan.view.colours import GREY, STATION_COLOURS, film_scale
from sprayplan.view.decimate import thin_surface
from sprayplan.view.scene import Scene, Surface

log = logging.getLogger(__name__)

#: Views: name -> (direction the viewer looks in, the image's up), all orthographic.
VIEWS = {
    "top": ((0.0, 0.0, -1.0), (0.0, 1.0, 0.0)),
    "below": ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0)),
    "from +x": ((-1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
    "from -x": ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
    "from +y": ((0.0, -1.0, 0.0), (0.0, 0.0, 1.0)),
    "from -y": ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
}
_FILE = {"top": "top", "below": "below", "from +x": "px", "from -x": "nx", "from +y": "py", "from -y": "ny"}
BACK = "#e6e6e6"


@dataclass(frozen=True)
class ReportSettings:
    """How the report draws.

    Attributes
    ----------
    size_px : (int, int)
        Width and height of every image, pixels.
    max_faces : int
        Triangles drawn in a film view (thinned beyond, ``view.decimate``).
    max_labels : int
        Stroke numbers written per station image at most (every k-th stroke beyond).
    """

    size_px: tuple = (1200, 900)
    max_faces: int = 40_000
    max_labels: int = 40


def view_frame(name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(right, up, toward the viewer) unit vectors of a named view: image x = p . right, y = p . up."""
    d, up = (np.array(v) for v in VIEWS[name])
    return np.cross(d, up), up, -d


def facing_area(surface: Surface, painted: np.ndarray) -> dict[str, float]:
    """Painted area each view sees, mm^2: the sum over painted vertices of area x max(0, n . toward viewer)."""
    area, normals = surface.area_mm2[painted], surface.normals[painted]
    out = {}
    for name in VIEWS:
        _, _, toward = view_frame(name)
        out[name] = float((area * np.maximum(normals @ toward, 0.0)).sum())
    return out


def film_views(scene: Scene) -> list[str]:
    """Top, and the two other views that see the most painted area (ties: the order of ``VIEWS``)."""
    painted = scene.painted
    if painted is None or not painted.any():
        return ["top", "from -y", "from +x"]
    area = facing_area(scene.surface, painted)
    others = sorted((name for name in VIEWS if name != "top"), key=lambda n: -area[n])
    return ["top", *others[:2]]


def _figure(settings: ReportSettings):
    from matplotlib.figure import Figure

    dpi = 100
    w, h = settings.size_px
    return Figure(figsize=(w / dpi, h / dpi), dpi=dpi)


def warm_up() -> None:
    """Draw a small picture with text into memory, so that matplotlib's fonts and canvas are set up (the
    helper process does this while it waits for work: ``parallel.HELPER_WARM_UPS``)."""
    import io

    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = _figure(ReportSettings())
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    ax.plot([0, 1], [0, 1])
    ax.set_title("warm-up")
    fig.savefig(io.BytesIO(), format="png")


def _save(fig, path: str) -> None:
    """Draw ``fig`` on its Agg canvas (the one ``_wrapped_title`` measured on, when it did) and write it as a PNG
    (zlib level 3), without its alpha channel when it is opaque throughout, as the report's images are: a
    quarter less to compress, the same picture."""
    from matplotlib import __version__
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from PIL import Image, PngImagePlugin

    from sprayplan.export.files import atomic_output

    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    canvas.draw()
    rgba = np.asarray(canvas.buffer_rgba())
    image = Image.frombuffer("RGBA", (rgba.shape[1], rgba.shape[0]), rgba, "raw", "RGBA", 0, 1)
    if (rgba[..., 3] == 255).all():
        image = image.convert("RGB")
    info = PngImagePlugin.PngInfo()
    info.add_text("Software", f"Matplotlib version{__version__}, https://matplotlib.org/")
    with atomic_output(path, "wb") as handle:
        image.save(handle, format="png", compress_level=3, dpi=(fig.dpi, fig.dpi), pnginfo=info)


def _polygons(surface: Surface, name: str):
    """The surface's triangles in a view, back to front: (k, 3, 2) corners, facing-the-viewer flags, order."""
    right, up, toward = view_frame(name)
    v = surface.vertices
    tri = surface.faces
    uv = np.column_stack([v @ right, v @ up])
    depth = (v @ toward)[tri].mean(axis=1)
    n = surface.normals[tri].sum(axis=1)
    facing = n @ toward > 0
    order = np.argsort(depth, kind="stable")
    return uv[tri[order]], facing[order], order


def draw_film(ax, scene: Scene, surface: Surface, name: str) -> None:
    """The film (or the bare part) in one view, onto a matplotlib axes."""
    from matplotlib.collections import PolyCollection
    from matplotlib.colors import to_rgba

    right, up, toward = view_frame(name)
    if len(surface.faces):
        polys, facing, order = _polygons(surface, name)
        if surface.thickness_um is not None:
            scale = film_scale(scene.target_um, scene.tolerance_um)
            film = surface.thickness_um[surface.faces[order]].mean(axis=1)
            colours = np.column_stack([scale.rgb(film), np.ones(len(film))])
        else:
            colours = np.tile(to_rgba(GREY), (len(polys), 1))
        colours[~facing] = to_rgba(BACK)
        ax.add_collection(PolyCollection(polys, facecolors=colours, edgecolors=colours, linewidths=0.3), autolim=False)
        ax.update_datalim(polys.reshape(-1, 2))
    else:  # a point cloud: each sample a disc of the area it stands for, back to front
        from matplotlib.collections import EllipseCollection

        p = surface.vertices
        uv = np.column_stack([p @ right, p @ up])
        order = np.argsort(p @ toward, kind="stable")
        if surface.thickness_um is not None:
            colours = film_scale(scene.target_um, scene.tolerance_um).rgb(surface.thickness_um)
        else:
            colours = np.tile(to_rgba(GREY)[:3], (len(p), 1))
        colours[surface.normals @ toward <= 0] = to_rgba(BACK)[:3]
        size = 2.0 * np.sqrt(np.maximum(surface.area_mm2, 1e-9) / np.pi)
        discs = EllipseCollection(
            size[order],
            size[order],
            np.zeros(len(p)),
            units="xy",
            offsets=uv[order],
            offset_transform=ax.transData,
            facecolors=colours[order],
            edgecolors="none",
        )
        ax.add_collection(discs, autolim=False)
        ax.update_datalim(np.vstack([uv.min(axis=0) - size.max(), uv.max(axis=0) + size.max()]))
    ax.set_aspect("equal")
    ax.autoscale_view()


def _axis_labels(ax, name: str) -> None:
    right, up, _ = view_frame(name)
    label = {(1, 0, 0): "x", (-1, 0, 0): "-x", (0, 1, 0): "y", (0, -1, 0): "-y", (0, 0, 1): "z", (0, 0, -1): "-z"}
    ax.set_xlabel(f"{label[tuple(round(c) for c in right)]} (mm)")
    ax.set_ylabel(f"{label[tuple(round(c) for c in up)]} (mm)")


def _colour_bar(fig, ax, scene: Scene) -> None:
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    scale = film_scale(scene.target_um, scene.tolerance_um)
    mappable = ScalarMappable(Normalize(scale.cmin, scale.cmax), scale.matplotlib())
    bar = fig.colorbar(mappable, ax=ax, shrink=0.8, pad=0.02, panchor=False)  # the view stays centred
    values, labels = scale.ticks
    bar.set_ticks(values, labels=labels)
    bar.set_label(f"dry film, um (spec {scene.target_um:g} +- {scene.tolerance_um:g})")


def film_picture(path: str, scene: Scene, surface: Surface, name: str, settings: ReportSettings) -> None:
    fig = _figure(settings)
    ax = fig.add_subplot()
    draw_film(ax, scene, surface, name)
    _axis_labels(ax, name)
    if surface.thickness_um is not None:
        _colour_bar(fig, ax, scene)
        title = f"{scene.name}: dry film, {name} (light grey: the back of a surface)"
    else:
        title = f"{scene.name}: {name} (no film simulated)"
    ax.set_title(title, fontsize=11)
    _finish(fig, ax)
    _save(fig, path)


def histogram_picture(path: str, scene: Scene, settings: ReportSettings) -> None:
    s = scene.surface
    painted = scene.painted
    t, w = s.thickness_um[painted], s.area_mm2[painted]
    lo, hi = scene.target_um - scene.tolerance_um, scene.target_um + scene.tolerance_um
    fig = _figure(settings)
    ax = fig.add_subplot()
    left = min(float(t.min()), lo - scene.tolerance_um)
    right = max(float(t.max()), hi + scene.tolerance_um)
    bins = np.linspace(left, right, 61)
    share = 100.0 * w / w.sum()
    ax.axvspan(lo, hi, color="#c7e9c0", alpha=0.6, label=f"spec {scene.target_um:g} +- {scene.tolerance_um:g} um")
    ax.hist(t, bins=bins, weights=share, color="#3182bd", edgecolor="white", linewidth=0.5, label="painted area")
    ax.axvline(scene.target_um, color="#238b45", linewidth=1.5, label="target")
    mean = float((t * w).sum() / w.sum())
    ax.axvline(mean, color="#444444", linestyle="--", linewidth=1.2, label=f"mean {mean:.1f} um")
    inside = float(w[(t >= lo) & (t <= hi)].sum() / w.sum())
    ax.set_xlabel("dry film, um")
    ax.set_ylabel("share of the painted area, % per bin")
    ax.set_title(
        f"{scene.name}: film over the painted area ({w.sum() / 1e6:.3f} m^2), {100 * inside:.1f} % in spec", fontsize=11
    )
    ax.legend(loc="upper right", fontsize=9)
    _finish(fig, ax)
    _save(fig, path)


class _Backdrop:
    """The part seen from above, light grey, drawn once as an image and shown behind every layout.

    Kept as it was drawn (transparent RGBA bytes) and, for drawing, as its colour channels on the axes' white
    (float images, one for all three when they are equal, as the grey's are): each picture resamples these
    once, to its own pixels, when it is drawn (``_BackdropImage``), instead of passing the whole image through
    ``imshow``'s checks and conversions at every layout. ``image`` is the same picture as float RGBA of alpha 1.
    """

    def __init__(self, surface: Surface | None, faces: int = 20_000, width_px: int = 1600):
        self.channels = None
        self._rgba = None
        if surface is None or not len(surface.vertices):
            return
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.collections import PolyCollection
        from matplotlib.figure import Figure
        from PIL import Image

        thin = thin_surface(surface, faces).surface
        lo, hi = thin.vertices[:, :2].min(axis=0), thin.vertices[:, :2].max(axis=0)
        span = np.maximum(hi - lo, 1e-6)
        lo, hi = lo - 0.01 * span, hi + 0.01 * span
        height_px = int(np.clip(width_px * (hi[1] - lo[1]) / (hi[0] - lo[0]), 16, 4 * width_px))
        fig = Figure(figsize=(width_px / 100, height_px / 100), dpi=100)
        canvas = FigureCanvasAgg(fig)
        ax = fig.add_axes((0, 0, 1, 1))
        ax.set_axis_off()
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        if len(thin.faces):
            polys = thin.vertices[thin.faces][:, :, :2]
            ax.add_collection(
                PolyCollection(polys, facecolors="#dddddd", edgecolors="#dddddd", linewidths=0.3), autolim=False
            )
        else:
            ax.scatter(thin.vertices[:, 0], thin.vertices[:, 1], s=0.5, c="#cccccc", linewidths=0)
        fig.patch.set_alpha(0.0)
        canvas.draw()
        self._rgba = np.array(canvas.buffer_rgba())
        alpha = self._rgba[..., 3] / np.float32(255.0)
        rgb = [self._rgba[..., k] for k in range(3)]
        same = [k for k in range(3) if np.array_equal(rgb[k], rgb[0])]
        #: (channels it stands for, float image "F" on white): the premultiplied colour plus the white left over
        self.channels = [
            (ks, Image.fromarray(rgb[ks[0]] / np.float32(255.0) * alpha + (1.0 - alpha), "F"))
            for ks in ([same] + [[k] for k in range(3) if k not in same])
        ]
        self.extent = (lo[0], hi[0], lo[1], hi[1])

    @property
    def image(self) -> np.ndarray | None:
        """The backdrop on the axes' white as float RGBA of alpha 1 (None without a part)."""
        if self._rgba is None:
            return None
        rgba = self._rgba.astype(np.float32) / 255.0
        alpha = rgba[..., 3:]
        return np.concatenate([rgba[..., :3] * alpha + (1.0 - alpha), np.ones_like(alpha)], axis=2)

    def draw(self, ax) -> None:
        if self.channels is not None:
            ax.add_artist(_BackdropImage(self))
            x0, x1, y0, y1 = self.extent
            ax.update_datalim(np.array([[x0, y0], [x1, y1]]))


class _BackdropImage(Artist):
    """A ``_Backdrop`` behind an axes' other artists (zorder 0; the axes' margins stop at its edges, as at an
    image's), resampled when drawn to the canvas pixels inside its extent as ``imshow(...,
    interpolation="bilinear")`` resamples an opaque float image (bilinear, the filter widened where the image
    shrinks, bytes by truncation); the pixels on its border stay the axes' white, as the image's margin is."""

    zorder = 0

    def __init__(self, backdrop: _Backdrop):
        super().__init__()
        self.backdrop = backdrop
        x0, x1, y0, y1 = backdrop.extent
        self.sticky_edges.x[:] = [x0, x1]
        self.sticky_edges.y[:] = [y0, y1]

    @allow_rasterization
    def draw(self, renderer) -> None:
        from PIL import Image

        if not self.get_visible():
            return
        x0, x1, y0, y1 = self.backdrop.extent
        (px0, py0), (px1, py1) = self.axes.transData.transform([(x0, y0), (x1, y1)])
        box = self.axes.bbox
        left, right = int(np.ceil(max(px0, box.x0))), int(np.floor(min(px1, box.x1)))
        bottom, top = int(np.ceil(max(py0, box.y0))), int(np.floor(min(py1, box.y1)))
        if right <= left or top <= bottom:
            return
        w, h = self.backdrop.channels[0][1].size
        source = (  # those pixels' edges in the image's pixels (its row 0 at the top)
            (left - px0) / (px1 - px0) * w,
            (py1 - top) / (py1 - py0) * h,
            (right - px0) / (px1 - px0) * w,
            (py1 - bottom) / (py1 - py0) * h,
        )
        shown = np.full((top - bottom, right - left, 4), 255, np.uint8)
        for ks, channel in self.backdrop.channels:
            resampled = channel.resize((right - left, top - bottom), Image.Resampling.BILINEAR, box=source)
            shown[..., ks] = (np.asarray(resampled)[::-1, :, None] * np.float32(255.0)).astype(np.uint8)
        gc = renderer.new_gc()
        gc.set_clip_rectangle(box)
        renderer.draw_image(gc, left, bottom, shown)  # its rows bottom up
        gc.restore()
        self.stale = False


def _finish(fig, ax=None, right: float = 0.97) -> None:
    """Fixed margins (tight_layout measures every label: slow, and the images are all alike)."""
    fig.subplots_adjust(left=0.08, right=right, bottom=0.08, top=0.92)


def _runs(items: list, key) -> list[list]:
    """``items`` cut into runs of neighbours with the same ``key(item)``, in order."""
    return [list(run) for _, run in itertools.groupby(items, key)]


def _stroke_lines(ax, lines: list[tuple], width: float, zorder: float) -> None:
    """Polylines ((k, 2) points, colour, line style) as line collections, one a run of one style, drawn in the
    order given: what one ``ax.plot`` a line drew (its caps: projecting when solid, butt when dashed)."""
    from matplotlib.collections import LineCollection

    for run in _runs(lines, lambda line: line[2]):
        style = run[0][2]
        ax.add_collection(
            LineCollection(
                [points for points, _, _ in run],
                colors=[colour for _, colour, _ in run],
                linewidths=width,
                linestyles=style,
                capstyle="projecting" if style == "-" else "butt",
                joinstyle="round",
                zorder=zorder,
            ),
            autolim=False,
        )


def _start_markers(ax, points: np.ndarray, colours: list):
    """Filled circles of 3 pt at ``points`` (data), each in its colour with a 1 pt edge of it: the markers of
    ``ax.plot(x, y, "o", markersize=3)``, as one collection."""
    from matplotlib.collections import PathCollection
    from matplotlib.markers import MarkerStyle
    from matplotlib.transforms import IdentityTransform

    marker = MarkerStyle("o")
    markers = PathCollection(
        [marker.get_path().transformed(marker.get_transform())],
        sizes=[3.0**2],
        offsets=points,
        offset_transform=ax.transData,
        facecolors=colours,
        edgecolors=colours,
        linewidths=1.0,
        zorder=3,
    )
    markers.set_transform(IdentityTransform())  # the marker's size in points (as scatter), not in data units
    return markers


def _wrapped_title(fig, text: str, fontsize: float) -> str:
    """``text`` broken into lines as matplotlib's ``wrap=True`` breaks an axes title centred on the figure (the
    most words a line that fits the figure's width about the title's centre), found by bisection: a few text
    measurements instead of one a word, at every layout pass."""
    import math

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.cbook import is_math_text
    from matplotlib.font_manager import FontProperties

    if is_math_text(text):
        return text
    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    renderer = canvas.get_renderer()  # the canvas ``_save`` then draws on: one renderer's buffer a picture
    prop = FontProperties(size=fontsize)
    box = fig.subplotpars
    centre = 0.5 * (box.left + box.right) * fig.bbox.width
    room = 2 * min(centre, fig.bbox.width - centre)

    def width(words) -> int:
        return math.ceil(renderer.get_text_width_height_descent(" ".join(words), prop, ismath=False)[0])

    lines = []
    for line in text.split("\n"):
        words = line.split(" ")
        while words:
            fit, over = 1, len(words) + 1  # words[:fit] fits (one word always goes), words[:over] does not
            if width(words) <= room:
                fit = len(words)
            else:
                over = len(words)
                while over - fit > 1:
                    mid = (fit + over) // 2
                    fit, over = (mid, over) if width(words[:mid]) <= room else (fit, mid)
            lines.append(" ".join(words[:fit]))
            words = words[fit:]
    return "\n".join(lines)


def station_picture(path: str, scene: Scene, place: int, settings: ReportSettings, backdrop: _Backdrop) -> None:
    from matplotlib import colormaps
    from matplotlib.patches import Circle

    st = scene.plan.stations[place]
    fig = _figure(settings)
    _finish(fig, None)
    ax = fig.add_subplot()
    backdrop.draw(ax)
    spray = [(i, s) for i, s in enumerate(st.strokes) if s.spray_on]
    cmap = colormaps["viridis"]
    step = max(1, int(np.ceil(len(spray) / settings.max_labels)))
    colours = [cmap(k / max(len(spray) - 1, 1)) for k in range(len(spray))]
    _stroke_lines(ax, [(s.points[:, :2], "#999999", "--") for s in st.strokes if not s.spray_on], width=0.6, zorder=1)
    _stroke_lines(
        ax,
        [(s.points[:, :2], c, "-" if s.kind == "spray" else ":") for (_i, s), c in zip(spray, colours)],
        width=1.2,
        zorder=2,
    )
    if spray:
        starts = np.array([s.points[0, :2] for _i, s in spray])
        ax.add_collection(_start_markers(ax, starts, colours), autolim=False)
    for k, (_i, s) in enumerate(spray):
        if k % step == 0 or k == len(spray) - 1:
            ax.annotate(
                str(k + 1),
                s.points[0, :2],
                fontsize=7,
                zorder=4,
                xytext=(3, 3),
                textcoords="offset points",
                bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.8),
            )
    p = st.platform_mm
    ax.add_patch(Circle(p[:2], scene.working_radius_mm, fill=False, ec="#7f7f7f", linestyle="--", zorder=1))
    ax.plot(p[0], p[1], "s", color=STATION_COLOURS[place % len(STATION_COLOURS)], markersize=8, zorder=5)
    for s in st.strokes:  # the data limits the lines' points gave
        ax.update_datalim(s.points[:, :2])
    ax.update_datalim(np.array([p[:2] - scene.working_radius_mm, p[:2] + scene.working_radius_mm]))
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    every = "" if step == 1 else f", every {step}th numbered"
    title = (
        f"{scene.name}: stop {place + 1} of {len(scene.plan.stations)} (station {st.index}), "
        f"{len(spray)} strokes (their paths on the part) from above, numbered at their start in the order run{every}; "
        "square: the platform, dashed circle: its working circle"
    )
    ax.set_title(_wrapped_title(fig, title, 9), fontsize=9)
    _save(fig, path)


def tour_picture(path: str, scene: Scene, settings: ReportSettings, backdrop: _Backdrop) -> None:
    from matplotlib.patches import Circle

    plan = scene.plan
    fig = _figure(settings)
    ax = fig.add_subplot()
    backdrop.draw(ax)
    stops = np.vstack([plan.home_mm, *[st.platform_mm for st in plan.stations], plan.home_mm])
    for a, b in itertools.pairwise(stops):
        ax.annotate("", b[:2], a[:2], arrowprops=dict(arrowstyle="-|>", color="#2ca02c", lw=1.5), zorder=3)
    for k, st in enumerate(plan.stations):
        p = st.platform_mm
        colour = STATION_COLOURS[k % len(STATION_COLOURS)]
        ax.add_patch(Circle(p[:2], scene.working_radius_mm, fill=False, ec=colour, alpha=0.7, zorder=2))
        ax.plot(p[0], p[1], "o", color=colour, markersize=7, zorder=4)
        ax.annotate(f"{k + 1}", p[:2], xytext=(5, 5), textcoords="offset points", fontsize=10, zorder=5)
        ax.update_datalim(np.array([p[:2] - scene.working_radius_mm, p[:2] + scene.working_radius_mm]))
    ax.plot(plan.home_mm[0], plan.home_mm[1], "s", color="#2ca02c", markersize=9, zorder=5)
    ax.annotate("home", plan.home_mm[:2], xytext=(6, -12), textcoords="offset points", fontsize=10)
    ax.update_datalim(stops[:, :2])
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    from sprayplan.view.summary import number

    travel = number(scene.totals.get("platform_travel_mm"))
    ax.set_title(
        f"{scene.name}: gantry tour, {len(plan.stations)} stops numbered in visiting order"
        + (f", {travel / 1000:.2f} m of travel" if travel is not None else "")
        + f"; circles: working circles (r {scene.working_radius_mm:.0f} mm)",
        fontsize=10,
    )
    _finish(fig, ax)
    _save(fig, path)


def measuring_picture(path: str, scene: Scene, settings: ReportSettings) -> None:
    index = scene.measuring_points
    t = scene.surface.thickness_um[index]
    lo, hi = scene.target_um - scene.tolerance_um, scene.target_um + scene.tolerance_um
    fig = _figure(settings)
    ax = fig.add_subplot()
    number = np.arange(1, len(t) + 1)
    ax.axhspan(lo, hi, color="#c7e9c0", alpha=0.6, label=f"spec {scene.target_um:g} +- {scene.tolerance_um:g} um")
    ax.plot(number, t, "-", color="#3182bd", linewidth=0.8)
    ax.plot(number, t, "o", color="#3182bd", markersize=2.5, label="film at the point")
    ax.axhline(scene.target_um, color="#238b45", linewidth=1.2, label="target")
    inside = float(((t >= lo) & (t <= hi)).mean())
    ax.set_xlim(0, len(t) + 1)
    pad = 2 * scene.tolerance_um or 0.1 * scene.target_um
    ax.set_ylim(min(float(t.min()), lo) - pad, max(float(t.max()), hi) + pad)
    ax.set_xlabel("measuring point")
    ax.set_ylabel("dry film, um")
    ax.set_title(
        f"{scene.name}: film at {len(t)} measuring points (seed 003, fig. 17): mean {t.mean():.1f} um, "
        f"{100 * inside:.1f} % in spec",
        fontsize=11,
    )
    ax.legend(loc="upper right", fontsize=9)
    _finish(fig, ax)
    _save(fig, path)


def write_report_files(
    folder: str, scene: Scene, settings: ReportSettings | None = None, progress=None, processes: int = 1
) -> list[str]:
    """Draw every image and write report.md into ``folder`` (an existing, empty folder); returns the paths.

    The images are drawn headless (matplotlib's Agg canvas, never pyplot), so no display is needed.
    ``progress(done, total)`` is called as images are done. With ``processes`` = 2 the images are shared
    with a helper process (``parallel.shared_map``; each image is drawn by the same code either way).
    """
    return begin_report_files(folder, scene, settings, progress, processes)()


def begin_report_files(
    folder: str, scene: Scene, settings: ReportSettings | None = None, progress=None, processes: int = 1
):
    """:func:`write_report_files` begun: with ``processes`` = 2 the helper process starts drawing now, while
    this process writes other files; the function returned takes part in the rest, writes report.md and
    returns the paths (it must be called)."""
    from sprayplan.parallel import shared_start

    settings = settings or ReportSettings()
    surface = scene.surface
    film = surface is not None and scene.painted is not None and bool(scene.painted.any())
    measured = scene.measuring_points is not None and len(scene.measuring_points) > 0
    pictures: list[tuple[str, str, str, object]] = []  # (file, caption, kind, argument)
    if surface is not None:
        for name in film_views(scene):
            what = "film" if surface.thickness_um is not None else "part"
            pictures.append((f"film_{_FILE[name]}.png", f"The {what}, {name}", "film", name))
        if film:
            pictures.append(("film_histogram.png", "The film over the painted area", "histogram", None))
        if measured:
            pictures.append(("measuring_points.png", "The film at the measuring points", "measuring", None))
    if scene.plan.stations:
        pictures.append(("gantry_tour.png", "The gantry tour", "tour", None))
    for place, st in enumerate(scene.plan.stations):
        caption = f"Stop {place + 1} (station {st.index}): its strokes in order"
        pictures.append((f"strokes_stop{place + 1:02d}.png", caption, "station", place))
    drawn = thin_surface(surface, settings.max_faces).surface if surface is not None else None
    # the histogram and the measuring points read the whole film: drawn here; the others need only the thinned
    # surface, the backdrop and the plan, which is all the helper is sent (the scene without its surface)
    here = [p for p in pictures if p[2] in ("histogram", "measuring")]
    shared = [p for p in pictures if p[2] not in ("histogram", "measuring")]
    light = replace(scene, surface=None)
    common = (folder, light, drawn, _Backdrop(surface), settings)
    if progress is not None:
        progress(0, len(pictures))
    count = {"here": 0, "shared": 0}

    def report(key, value):
        count[key] = value
        if progress is not None:
            progress(count["here"] + count["shared"], len(pictures))

    drawing = shared_start(_draw_picture, shared, processes, done=lambda done: report("shared", done), common=common)

    def finish() -> list[str]:
        from sprayplan.export.files import atomic_output

        try:
            for k, picture in enumerate(here):
                _draw_picture((folder, scene, drawn, None, settings), picture)
                report("here", k + 1)
        finally:
            drawing.finish()
        images = [(file, caption) for file, caption, _, _ in pictures]
        with atomic_output(os.path.join(folder, "report.md"), "w", encoding="utf-8") as handle:
            handle.write(report_markdown(scene, images))
        return [os.path.join(folder, f) for f, _ in images] + [os.path.join(folder, "report.md")]

    return finish


def _draw_picture(common, picture) -> None:
    """One image of the report (``write_report_files``'s ``(file, caption, kind, argument)``) into its folder."""
    folder, scene, drawn, backdrop, settings = common
    file, _, kind, argument = picture
    path = os.path.join(folder, file)
    if kind == "film":
        film_picture(path, scene, drawn, argument, settings)
    elif kind == "histogram":
        histogram_picture(path, scene, settings)
    elif kind == "measuring":
        measuring_picture(path, scene, settings)
    elif kind == "tour":
        tour_picture(path, scene, settings, backdrop)
    else:
        station_picture(path, scene, argument, settings, backdrop)


def report_markdown(scene: Scene, images: list[tuple[str, str]]) -> str:
    """report.md: the summary tables (as the viewer's), the stations' table and the images."""
    from sprayplan.view.summary import summary_rows

    lines = [f"# sprayplan report: {scene.name}", ""]
    for note in scene.notes:
        lines += [f"> {note}", ""]
    for title, rows in summary_rows(scene):
        lines += [f"## {title[0].upper()}{title[1:]}", "", "| | |", "|---|---|"]
        lines += [f"| {k} | {v} |" for k, v in rows] + [""]
    lines += [
        "## Stations",
        "",
        "| stop | station | platform x, y, z (mm) | spray strokes | waypoints | unreachable |",
        "|---|---|---|---|---|---|",
    ]
    for place, st in enumerate(scene.plan.stations):
        p = st.platform_mm
        spray = sum(1 for s in st.strokes if s.spray_on)
        lines.append(
            f"| {place + 1} | {st.index} | {p[0]:.0f}, {p[1]:.0f}, {p[2]:.0f} | {spray} | {len(st.reachable)} "
            f"| {int((~st.reachable).sum())} |"
        )
    lines.append("")
    for file, caption in images:
        lines += [f"## {caption}", "", f"![{caption}]({file})", ""]
    return "\n".join(lines)
