"""The faster output writers (issue 17) write what the writers they replaced wrote, each kept here as it was:

- waypoints.csv, formatted a column at a time, is byte for byte the file the row-by-row writer gave, also for
  values that are not finite, signed zeros, tiny and huge numbers;
- thickness.csv, formatted a block of rows in one operation, is byte for byte ``np.savetxt``'s, across blocks;
- a station's picture, its strokes drawn as line collections, its start markers as one collection, its title
  wrapped once and the part's backdrop opaque, looks as the picture drawn one ``ax.plot`` a stroke did (the
  same pixels but for anti-aliasing at sub-pixel marker positions), and the title breaks where matplotlib's
  ``wrap=True`` breaks it.
"""

from __future__ import annotations

import dataclasses
import io
from types import SimpleNamespace

import numpy as np
import pytest

from sprayplan.export import film as film_module
from sprayplan.export.film import write_thickness_csv
from sprayplan.export.plan_json import tip_speeds, write_waypoints_csv
from sprayplan.export.plan_read import read_plan_file
from sprayplan.view import report
from sprayplan.view.colours import STATION_COLOURS
from sprayplan.view.decimate import thin_surface
from sprayplan.view.scene import scene_from_folder


def _old_waypoints_csv(path, plan, job, timing=None) -> None:
    """waypoints.csv as written before: every row through numpy scalars, one write a row."""
    header = (
        "station,stroke,waypoint,spray_on,x,y,z,ax,ay,az,q1,q2,q3,q4,q5,q6,tx,ty,tz,reachable,position_error_mm,"
        "axis_error_deg,speed_mm_s"
    )
    header += ",t_s,achievable_speed_mm_s" if timing is not None else ""
    header += ",collision,motion_collision,collision_distance_mm,collision_with,repair\n"
    with open(path, "w", newline="") as handle:
        handle.write(header)
        for place, st in enumerate(plan.stations):
            start = 0
            for i, s in enumerate(st.strokes):
                n = len(s)
                q = st.q9[start : start + n]
                ok = st.reachable[start : start + n]
                table = np.column_stack(
                    [
                        np.full(n, place),
                        np.full(n, i),
                        np.arange(n),
                        np.full(n, int(s.spray_on)),
                        s.tcp,
                        -s.normals,
                        np.where(ok[:, None], q, np.nan),
                        ok.astype(int),
                        st.position_error_mm[start : start + n],
                        st.axis_error_deg[start : start + n],
                        tip_speeds(s, job),
                    ]
                )
                if timing is not None:
                    times = timing.t_s[place][start : start + n]
                    speeds = timing.speed_mm_s[place][start : start + n]
                    table = np.column_stack([table, times, speeds])
                sl = slice(start, start + n)
                distance = st.collision_distance_mm[sl]
                extra = [
                    f"{int(c)},{int(m)},{'' if not np.isfinite(d) else f'{d:.6g}'},{w},{r}"
                    for c, m, d, w, r in zip(
                        st.collision[sl], st.motion_collision[sl], distance, st.collision_with[sl], st.repair[sl]
                    )
                ]
                for k, row in enumerate(table):
                    cells = (
                        [f"{int(v)}" for v in row[:4]]
                        + ["" if not np.isfinite(v) else f"{v:.10g}" for v in row[4:19]]
                        + [f"{int(row[19])}"]
                        + ["" if not np.isfinite(v) else f"{v:.6g}" for v in row[20:22]]
                        + [f"{row[22]:.6g}"]
                        + ["" if not np.isfinite(v) else f"{v:.10g}" for v in row[23:]]
                    )
                    handle.write(",".join(cells) + "," + extra[k] + "\n")
                start += n


ODD = np.array([np.nan, np.inf, -np.inf, -0.0, 0.0, 1e-300, 5e-324, -1.5e17, 123456789.123456789, 0.1, 2.5, 1e16])


def _odd(values: np.ndarray, shift: int) -> np.ndarray:
    """``values`` with the odd numbers above written into every third place (from ``shift``)."""
    out = np.array(values, dtype=float, copy=True)
    flat = out.reshape(-1)
    index = np.arange(shift % 3, len(flat), 3)
    flat[index] = ODD[np.arange(len(index)) % len(ODD)]
    return out


def _odd_plan(plan):
    """The plan with odd numbers in its errors and clearances, a few waypoints unreachable and collision names."""
    stations = []
    for k, st in enumerate(plan.stations):
        n = len(st.reachable)
        reachable = st.reachable.copy()
        reachable[k % 5 :: 5] = False
        stations.append(
            dataclasses.replace(
                st,
                q9=_odd(st.q9, k),
                reachable=reachable,
                method=np.where(reachable, st.method, ""),
                position_error_mm=_odd(st.position_error_mm, k + 1),
                axis_error_deg=_odd(st.axis_error_deg, k + 2),
                collision_distance_mm=_odd(st.collision_distance_mm, k),
                collision=np.arange(n) % 4 == 0,
                collision_with=np.array(["", "floor", "part, nan", "inf"] * (n // 4 + 1))[:n],
            )
        )
    return dataclasses.replace(plan, stations=tuple(stations))


@pytest.fixture(scope="module")
def read(planned_with_film):
    return read_plan_file(planned_with_film / "plan.json")


@pytest.mark.parametrize("odd", [False, True])
@pytest.mark.parametrize("timed", [True, False])
def test_waypoints_csv_is_the_old_writers_file(read, tmp_path, odd, timed):
    plan = _odd_plan(read.plan) if odd else read.plan
    timing = read.timing if timed else None
    if timed and odd:
        timing = dataclasses.replace(
            timing, t_s=tuple(_odd(t, 1) for t in timing.t_s), speed_mm_s=tuple(_odd(v, 2) for v in timing.speed_mm_s)
        )
    assert timing is not None or not timed
    write_waypoints_csv(tmp_path / "new.csv", plan, read.job, timing)
    _old_waypoints_csv(tmp_path / "old.csv", plan, read.job, timing)
    new, old = (tmp_path / "new.csv").read_bytes(), (tmp_path / "old.csv").read_bytes()
    assert new == old
    assert new.count(b"\n") == 1 + sum(len(st.reachable) for st in plan.stations)


@pytest.mark.parametrize("block", [7, 1 << 16])
def test_thickness_csv_is_savetxts_file(tmp_path, monkeypatch, block):
    monkeypatch.setattr(film_module, "_CSV_BLOCK", block)
    rng = np.random.default_rng(3)
    n = 50
    points = _odd(rng.normal(0.0, 800.0, (n, 3)), 0)
    points[np.isinf(points)] = 1e300  # a film sample is finite; savetxt's text for the extremes all the same
    points[np.isnan(points)] = -2.5e-7
    thickness = np.r_[rng.uniform(0, 90, n - 4), 0.00005, 0.00015, -0.0, 49.99995]
    result = SimpleNamespace(points=points, thickness_um=thickness)  # what the writer reads of a CoatingResult
    write_thickness_csv(tmp_path / "new.csv", result)
    buffer = io.StringIO()
    np.savetxt(buffer, np.column_stack([points, thickness]), fmt=["%.6f", "%.6f", "%.6f", "%.4f"], delimiter=",")
    assert (tmp_path / "new.csv").read_text() == "x,y,z,thickness_um\n" + buffer.getvalue()


class _OldBackdrop:
    """The backdrop as drawn before: the part from above, light grey, kept as transparent RGBA bytes."""

    def __init__(self, surface, faces: int = 20_000, width_px: int = 1600):
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.collections import PolyCollection
        from matplotlib.figure import Figure

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
        polys = thin.vertices[thin.faces][:, :, :2]
        ax.add_collection(
            PolyCollection(polys, facecolors="#dddddd", edgecolors="#dddddd", linewidths=0.3), autolim=False
        )
        fig.patch.set_alpha(0.0)
        canvas.draw()
        self.image = np.asarray(canvas.buffer_rgba()).copy()
        self.extent = (lo[0], hi[0], lo[1], hi[1])

    def draw(self, ax) -> None:
        ax.imshow(self.image, extent=self.extent, origin="upper", interpolation="bilinear", zorder=0)
        x0, x1, y0, y1 = self.extent
        ax.update_datalim(np.array([[x0, y0], [x1, y1]]))


def _old_station_picture(path, scene, place, settings, backdrop) -> None:
    """A station's picture as drawn before: one ``ax.plot`` a stroke and a start marker, ``wrap=True``."""
    from matplotlib import colormaps
    from matplotlib.patches import Circle

    st = scene.plan.stations[place]
    fig = report._figure(settings)
    ax = fig.add_subplot()
    backdrop.draw(ax)
    spray = [(i, s) for i, s in enumerate(st.strokes) if s.spray_on]
    cmap = colormaps["viridis"]
    step = max(1, int(np.ceil(len(spray) / settings.max_labels)))
    for k, (_i, s) in enumerate(spray):
        colour = cmap(k / max(len(spray) - 1, 1))
        style = "-" if s.kind == "spray" else ":"
        ax.plot(s.points[:, 0], s.points[:, 1], color=colour, linewidth=1.2, zorder=2, linestyle=style)
        ax.plot(s.points[0, 0], s.points[0, 1], "o", color=colour, markersize=3, zorder=3)
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
    for s in st.strokes:
        if not s.spray_on:
            ax.plot(s.points[:, 0], s.points[:, 1], color="#999999", linewidth=0.6, linestyle="--", zorder=1)
    p = st.platform_mm
    ax.add_patch(Circle(p[:2], scene.working_radius_mm, fill=False, ec="#7f7f7f", linestyle="--", zorder=1))
    ax.plot(p[0], p[1], "s", color=STATION_COLOURS[place % len(STATION_COLOURS)], markersize=8, zorder=5)
    ax.update_datalim(np.array([p[:2] - scene.working_radius_mm, p[:2] + scene.working_radius_mm]))
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    every = "" if step == 1 else f", every {step}th numbered"
    ax.set_title(
        f"{scene.name}: stop {place + 1} of {len(scene.plan.stations)} (station {st.index}), "
        f"{len(spray)} strokes (their paths on the part) from above, numbered at their start in the order run{every}; "
        "square: the platform, dashed circle: its working circle",
        fontsize=9,
        wrap=True,
    )
    report._finish(fig, ax)
    report._save(fig, path)


def _pixels(path) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(path).convert("RGB"), dtype=int)


def test_a_station_picture_looks_as_the_old_one(planned_with_film, tmp_path):
    scene = scene_from_folder(planned_with_film)
    settings = report.ReportSettings()
    new_backdrop, old_backdrop = report._Backdrop(scene.surface), _OldBackdrop(scene.surface)
    assert new_backdrop.image.shape[2] == 4 and (new_backdrop.image[..., 3] == 1).all()
    most = 0
    for place in range(len(scene.plan.stations)):
        report.station_picture(tmp_path / "new.png", scene, place, settings, new_backdrop)
        _old_station_picture(tmp_path / "old.png", scene, place, settings, old_backdrop)
        new, old = _pixels(tmp_path / "new.png"), _pixels(tmp_path / "old.png")
        assert new.shape == old.shape == (settings.size_px[1], settings.size_px[0], 3)
        diff = np.abs(new - old).max(axis=2)
        assert (diff > 3).mean() < 0.002, place  # a few hundred pixels: where a marker's edge falls in a pixel
        assert (diff > 0).mean() < 0.15, place  # the backdrop's grey within one level of 255 elsewhere
        # the strokes and their start markers all drawn: as many coloured (not grey) pixels, within 2 %
        coloured = [int((image.max(axis=2) - image.min(axis=2) > 30).sum()) for image in (new, old)]
        assert coloured[1] > 0 and abs(coloured[0] / coloured[1] - 1) < 0.02, (place, coloured)
        most = max(most, coloured[1])
    assert most > 1000  # a station with many strokes among them


@pytest.mark.parametrize("words", [3, 30, 60])
def test_the_title_breaks_where_matplotlib_wraps_it(words):
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    text = " ".join(f"word{k}" + "x" * (k % 7) for k in range(words)) + "\nsecond line, short"
    fig = report._figure(report.ReportSettings())
    report._finish(fig)
    ax = fig.add_subplot()
    title = ax.set_title(text, fontsize=9, wrap=True)
    FigureCanvasAgg(fig).draw()
    assert report._wrapped_title(fig, text, 9) == title._get_wrapped_text()


def test_the_backdrop_is_the_transparent_one_on_white(planned_with_film):
    scene = scene_from_folder(planned_with_film)
    new, old = report._Backdrop(scene.surface), _OldBackdrop(scene.surface)
    assert new.extent == old.extent
    alpha = old.image[..., 3:] / 255.0
    on_white = old.image[..., :3] / 255.0 * alpha + (1.0 - alpha)
    assert np.allclose(new.image[..., :3], on_white, atol=1e-6)
    assert (new.image[..., 3] == 1.0).all()
    assert 0.05 < (alpha == 1).mean() < 0.95  # the part and the room around it both there
