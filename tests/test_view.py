"""The pictures of a plan (sprayplan.view): the self-contained HTML viewer and the PNG picture report, checked
against the plan and film files they draw (no browser here: see test_view_browser.py)."""

from __future__ import annotations

import json
import shutil
from html.parser import HTMLParser

import numpy as np
import pytest

from sprayplan.cli import main
from sprayplan.export.film import read_thickness_ply
from sprayplan.export.plan_json import tip_speeds
from sprayplan.export.plan_read import read_plan_file
from sprayplan.view.colours import GREY, SPEC_MID, film_scale, hex_rgb
from sprayplan.view.decimate import cluster, thin_indices, thin_surface
from sprayplan.view.html import ViewerLimits, build_figure, read_viewer_figure
from sprayplan.view.report import ReportSettings, film_views
from sprayplan.view.scene import Surface, scene_from_folder, vertex_areas

REGION = "x > -250"


@pytest.fixture(scope="module")
def planned(planned_with_film):
    return planned_with_film


@pytest.fixture(scope="module")
def bare(testdata, tmp_path_factory):
    """The same part planned without a film."""
    out = tmp_path_factory.mktemp("bare")
    part = testdata / "meshes" / "reach_curved_part.ply"
    assert main(["-q", "plan", str(part), "--units", "m", "--region", REGION, "-o", str(out)]) == 0
    return out


def _figure(folder):
    return read_viewer_figure((folder / "plan.html").read_text(encoding="utf-8"))


def _points(trace) -> np.ndarray:
    xyz = np.column_stack([np.asarray(trace[k], float) for k in "xyz"])
    return xyz[np.isfinite(xyz).all(axis=1)]


class _Tags(HTMLParser):
    def __init__(self):
        super().__init__()
        self.tags, self.styles, self._in_style = [], [], False

    def handle_starttag(self, tag, attrs):
        self.tags.append((tag, dict(attrs)))
        self._in_style = tag == "style"

    def handle_endtag(self, tag):
        self._in_style = False

    def handle_data(self, data):
        if self._in_style:
            self.styles.append(data)


def test_the_viewer_needs_no_network(planned):
    page = (planned / "plan.html").read_text(encoding="utf-8")
    tags = _Tags()
    tags.feed(page)
    scripts = [attrs for tag, attrs in tags.tags if tag == "script"]
    assert scripts and all("src" not in attrs for attrs in scripts)  # plotly.js is inline
    for tag, attrs in tags.tags:
        for key in ("src", "href"):
            assert "//" not in attrs.get(key, ""), (tag, attrs)
    assert all("url(" not in css and "@import" not in css for css in tags.styles)
    assert "plotly.js v" in page and len(page) > 3_000_000  # the library itself is embedded


def test_the_viewer_draws_the_film_values_on_the_part(planned):
    data, _ = _figure(planned)
    film = read_thickness_ply(planned / "thickness.ply")
    (part,) = [t for t in data if t.get("legendgroup") == "part"]
    assert part["type"] == "mesh3d" and len(film.faces) <= ViewerLimits().max_faces  # drawn whole
    assert np.array_equal(part["intensity"], film.thickness_um.astype(np.float32))
    assert np.array_equal(np.column_stack([part["i"], part["j"], part["k"]]), film.faces)
    assert np.array_equal(np.column_stack([part[k] for k in "xyz"]), film.points.astype(np.float32))
    coating = json.loads((planned / "coating.json").read_text())
    target, tol = coating["spec"]["target_um"], coating["spec"]["tolerance_um"]
    ticks = part["colorbar"]["tickvals"]
    assert {target - tol, target, target + tol} <= set(ticks)
    assert part["cmin"] < target - tol and part["cmax"] > target + tol
    # diverging about the target: the scale's middle colour is at the target
    at = {c[0]: c[1] for c in part["colorscale"]}
    assert at[(target - part["cmin"]) / (part["cmax"] - part["cmin"])] == SPEC_MID


def test_thickness_ply_reads_back_with_the_area_of_each_sample(planned):
    film = read_thickness_ply(planned / "thickness.ply")
    coating = json.loads((planned / "coating.json").read_text())
    assert film.area_mm2.sum() == pytest.approx(coating["all"]["area_mm2"], rel=1e-5)
    assert len(film.points) == coating["all"]["count"]
    painted = film.thickness_um >= coating["spec"]["painted_fraction"] * coating["spec"]["target_um"]
    mean = (film.thickness_um * film.area_mm2)[painted].sum() / film.area_mm2[painted].sum()
    assert mean == pytest.approx(coating["painted"]["mean_um"], rel=1e-5)
    # the samples' areas are a third of their triangles' (the weights the film's statistics use)
    assert np.allclose(vertex_areas(film.points, film.faces), film.area_mm2, rtol=1e-4, atol=1e-3)


def test_the_strokes_carry_their_plan_data(planned):
    data, _ = _figure(planned)
    read = read_plan_file(planned / "plan.json")
    plan, job = read.plan, read.job
    strokes = [t for t in data if t.get("legendgroup") in ("strokes", "transfers")]
    names = [t["name"] for t in strokes if t["legendgroup"] == "strokes"]
    with_kind = lambda kind: sum(any(s.kind == kind for s in st.strokes) for st in plan.stations)
    assert len([n for n in names if not n.endswith("touch-ups")]) == with_kind("spray")
    assert len([n for n in names if n.endswith("touch-ups")]) == with_kind("touch-up") > 0
    # the rows between polylines are all NaN; a waypoint's achievable speed and time stamp may be NaN (transfers,
    # unreachable waypoints)
    rows = np.vstack([t["customdata"][np.isfinite(t["customdata"][:, :5]).all(axis=1)] for t in strokes])
    assert len(rows) == sum(len(s) for s in plan.strokes)  # every waypoint, none thinned at this size
    by_key = {(int(r[0]), int(r[1]), int(r[2])): r[3:] for r in rows}
    assert read.timing is not None and rows.shape[1] == 7
    for place, st in enumerate(plan.stations):
        start = 0
        for i, s in enumerate(st.strokes):
            speed = tip_speeds(s, job)
            for j in (0, len(s) - 1):
                got = by_key[(st.index, i, j)]
                assert got[0] == pytest.approx(speed[j], rel=1e-6) and got[1] == pytest.approx(s.dwell[j], rel=1e-6)
                achieved, stamp = read.timing.speed_mm_s[place][start + j], read.timing.t_s[place][start + j]
                np.testing.assert_allclose(got[2:], np.float32([achieved, stamp]), rtol=1e-6, equal_nan=True)
            start += len(s)
    tcp = np.vstack([_points(t) for t in strokes])
    expected = np.vstack([s.tcp for s in plan.strokes]).astype(np.float32)
    assert len(tcp) == len(expected)
    assert np.allclose(np.sort(tcp, axis=0), np.sort(expected, axis=0))
    (transfers,) = [t for t in strokes if t["legendgroup"] == "transfers"]
    assert transfers["line"]["dash"] == "dash"


def test_the_layer_buttons_switch_whole_legend_groups(planned):
    data, layout = _figure(planned)
    (menu,) = layout["updatemenus"]
    labels = [b["label"] for b in menu["buttons"]]
    assert labels == ["part", "strokes", "transfers", "gun axis", "gantry", "flagged"]
    for button in menu["buttons"]:
        index = button["args"][1]
        assert index == button["args2"][1]
        groups = {data[i]["legendgroup"] for i in index}
        wanted = {"gantry": {"stations", "tour"}}.get(button["label"], {button["label"]})
        assert groups == wanted and set(index) == {i for i, t in enumerate(data) if t["legendgroup"] in wanted}
        first, second = button["args"][0]["visible"], button["args2"][0]["visible"]
        hidden_at_first = button["label"] == "gun axis"
        assert set(first) == {True if hidden_at_first else "legendonly"} and set(second) != set(first)


def test_stations_tour_and_flags_match_the_plan(planned):
    data, _ = _figure(planned)
    plan = read_plan_file(planned / "plan.json").plan
    by_name = {t["name"]: t for t in data}
    stations = next(t for n, t in by_name.items() if n.startswith("stations"))
    platforms = np.array([st.platform_mm for st in plan.stations], np.float32)
    assert np.array_equal(_points(stations), platforms)
    tour = next(t for n, t in by_name.items() if n.startswith("gantry tour"))
    assert len(_points(tour)) == len(plan.stations) + 2
    assert np.array_equal(_points(tour)[0], plan.home_mm.astype(np.float32))
    reach = np.concatenate([st.reachable for st in plan.stations])
    flags = {t["name"].split(" (")[0]: len(_points(t)) for t in data if t.get("legendgroup") == "flagged"}
    assert flags.get("unreachable waypoints", 0) == int((~reach).sum())
    sqp = np.concatenate(
        [
            (st.method == "sqp") & st.reachable & ((st.position_error_mm > 0.01) | (st.axis_error_deg > 0.01))
            for st in plan.stations
        ]
    )
    assert flags.get("waypoints reached only within the tolerance", 0) == int(sqp.sum())


def test_the_summary_panel_shows_the_plan_and_film_figures(planned):
    page = (planned / "plan.html").read_text(encoding="utf-8")
    coating = json.loads((planned / "coating.json").read_text())
    totals = json.loads((planned / "plan.json").read_text())["totals"]
    header = page[: page.index("<script")]
    assert f"{coating['painted']['mean_um']:.1f} um" in header
    assert f"{100 * coating['painted']['share_in_spec']:.1f} % of the painted area" in header
    assert f"{totals['cycle_time_s']:,.0f} s" in header
    assert f"<td class='v'>{totals['stations']}</td>" in header


def test_view_redraws_a_plan_folder_the_same(planned, tmp_path):
    copy = tmp_path / "copy"
    shutil.copytree(planned, copy)
    (copy / "plan.html").unlink()
    shutil.rmtree(copy / "report")
    assert main(["-q", "view", str(copy)]) == 0
    drawn, _ = _figure(copy)
    written, _ = _figure(planned)
    assert [t["name"] for t in drawn] == [t["name"] for t in written]
    for a, b in zip(drawn, written):
        for key in ("x", "y", "z", "intensity", "customdata"):
            if key in a:
                assert np.array_equal(np.asarray(a[key]), np.asarray(b[key]), equal_nan=True), (a["name"], key)
    assert sorted(p.name for p in (copy / "report").iterdir()) == sorted(p.name for p in (planned / "report").iterdir())


def _png_size(path) -> tuple[int, int]:
    head = path.read_bytes()[:24]
    assert head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR"
    return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")


def _pixels(path) -> np.ndarray:
    from matplotlib.image import imread

    return imread(path)[:, :, :3]


def test_the_report_images_are_of_the_plan(planned):
    report = planned / "report"
    plan = read_plan_file(planned / "plan.json").plan
    names = sorted(p.name for p in report.glob("*.png"))
    films = [n for n in names if n.startswith("film_") and n != "film_histogram.png"]
    assert "film_top.png" in films and len(films) == 3
    assert {"film_histogram.png", "gantry_tour.png", "measuring_points.png"} <= set(names)
    assert len([n for n in names if n.startswith("strokes_stop")]) == len(plan.stations)
    for name in names:
        assert _png_size(report / name) == ReportSettings().size_px
        pixels = _pixels(report / name)
        assert len(np.unique((pixels * 255).round().reshape(-1, 3), axis=0)) > 50, name  # not blank
    # the film's picture shows the film's colours: the scale's colour of the median film covers a good part
    coating = json.loads((planned / "coating.json").read_text())
    scale = film_scale(coating["spec"]["target_um"], coating["spec"]["tolerance_um"])
    film = read_thickness_ply(planned / "thickness.ply")
    painted = film.thickness_um >= 0.1 * coating["spec"]["target_um"]
    expected = scale.rgb([np.median(film.thickness_um[painted])])[0]
    pixels = _pixels(report / "film_top.png").reshape(-1, 3)
    near = np.abs(pixels - expected).max(axis=1) < 0.08
    assert near.mean() > 0.02
    md = (report / "report.md").read_text()
    for name in names:
        assert f"]({name})" in md
    assert f"{coating['painted']['mean_um']:.1f} um" in md


def test_without_a_film_the_part_is_grey_with_a_note(bare):
    data, _ = _figure(bare)
    (part,) = [t for t in data if t.get("legendgroup") == "part"]
    assert part["color"] == GREY and "intensity" not in part
    page = (bare / "plan.html").read_text(encoding="utf-8")
    assert "no film was simulated" in page[: page.index("<script")]
    names = {p.name for p in (bare / "report").glob("*.png")}
    assert "film_top.png" in names and "film_histogram.png" not in names
    # the view command finds the part again through plan.json and draws the same grey part
    before = np.asarray(part["x"])
    assert main(["-q", "view", str(bare), "--no-report"]) == 0
    (again,) = [t for t in _figure(bare)[0] if t.get("legendgroup") == "part"]
    assert np.array_equal(np.asarray(again["x"]), before)


def test_no_viewer_and_no_report(testdata, tmp_path):
    part = testdata / "meshes" / "reach_curved_part.ply"
    out = tmp_path / "out"
    argv = ["-q", "plan", str(part), "--units", "m", "--region", "x > -150", "--no-viewer", "--no-report"]
    assert main([*argv, "-o", str(out)]) == 0
    assert not (out / "plan.html").exists() and not (out / "report").exists()
    assert (out / "plan.json").exists()


def test_view_refuses_what_is_not_a_plan(planned, tmp_path, capsys):
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["view", str(empty)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(empty) in err[0] and "no plan.json" in err[0]
    assert list(empty.iterdir()) == []

    other = tmp_path / "other"
    shutil.copytree(planned, other)
    before = (other / "plan.html").read_bytes()
    data = json.loads((other / "plan.json").read_text())
    data["version"] = 99
    (other / "plan.json").write_text(json.dumps(data))
    assert main(["view", str(other)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "plan.json" in err[0] and "99" in err[0]
    assert (other / "plan.html").read_bytes() == before  # left as it was

    broken = tmp_path / "broken"
    shutil.copytree(planned, broken)
    ply = broken / "thickness.ply"
    ply.write_bytes(ply.read_bytes()[:-100])
    assert main(["view", str(broken)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "thickness.ply" in err[0]
    assert (broken / "plan.html").read_bytes() == before
    assert not [p for p in broken.iterdir() if p.name.startswith(".")]  # no staging folder left

    assert main(["view", str(planned), "--no-viewer", "--no-report"]) == 2
    assert "--no-viewer" in capsys.readouterr().err


def _sheet(z: float, normal_z: float, n: int = 40, film: float = 50.0) -> Surface:
    g = np.linspace(0.0, 100.0, n)
    x, y = np.meshgrid(g, g)
    v = np.column_stack([x.ravel(), y.ravel(), np.full(n * n, z)])
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    faces = np.vstack([np.column_stack([a, b, d]), np.column_stack([a, d, c])])
    if normal_z < 0:
        faces = faces[:, ::-1]
    normals = np.tile([0.0, 0.0, normal_z], (n * n, 1))
    t = film + 10.0 * np.sin(v[:, 0] / 15.0)
    return Surface(v, faces, normals, vertex_areas(v, faces), t)


def _joined(*surfaces: Surface) -> Surface:
    offset = np.cumsum([0] + [len(s.vertices) for s in surfaces[:-1]])
    return Surface(
        np.vstack([s.vertices for s in surfaces]),
        np.vstack([s.faces + o for s, o in zip(surfaces, offset)]),
        np.vstack([s.normals for s in surfaces]),
        np.concatenate([s.area_mm2 for s in surfaces]),
        np.concatenate([s.thickness_um for s in surfaces]),
    )


def test_thinning_keeps_area_and_mean_film_and_the_two_sides_of_a_sheet_apart():
    top = _sheet(1.0, 1.0, film=50.0)
    bottom = _sheet(0.0, -1.0, film=0.0)  # the sheet's underside, 1 mm below, unpainted
    both = _joined(top, bottom)
    thinned = thin_surface(both, 600)
    s = thinned.surface
    assert len(s.faces) <= 600 and thinned.cell_mm > 1.0  # cells far larger than the sheet's thickness
    assert s.area_mm2.sum() == pytest.approx(both.area_mm2.sum())
    mean = lambda surf: (surf.thickness_um * surf.area_mm2).sum() / surf.area_mm2.sum()
    assert mean(s) == pytest.approx(mean(both))
    up = s.normals[:, 2] > 0
    # never a blend of the painted top and the bare underside
    assert s.thickness_um[up].min() >= 40.0 - 1e-9 and s.thickness_um[~up].max() <= 10.0 + 1e-9
    assert np.all(np.isin(np.unique(s.faces), np.arange(len(s.vertices))))
    # a surface within the budget is drawn as it is
    assert thin_surface(top, 10_000).surface is top
    # clustering in cells smaller than the vertex spacing changes nothing but the order
    same = cluster(top, 0.5)
    assert len(same.vertices) == len(top.vertices) and len(same.faces) == len(top.faces)


def test_thin_indices_keep_both_ends_and_the_budget():
    keep = thin_indices([1000, 3, 1, 500], 300)
    assert all(k[0] == 0 and k[-1] == n - 1 for k, n in zip(keep, [1000, 3, 1, 500]))
    assert sum(len(k) for k in keep) <= 300 + 2 * 4
    assert [len(k) for k in thin_indices([10, 20], 100)] == [10, 20]


def test_the_film_scale_in_plotly_and_matplotlib_agree():
    scale = film_scale(50.0, 5.0)
    assert (scale.cmin, scale.cmax) == (30.0, 70.0)
    values, labels = scale.ticks
    assert values == [30.0, 45.0, 50.0, 55.0, 70.0] and "target" in labels[2]
    cmap = scale.matplotlib()
    for film in (31.0, 40.0, 47.0, 50.0, 53.0, 60.0, 69.0):
        assert np.allclose(cmap(scale.fraction(film))[:3], scale.rgb([film])[0], atol=3 / 255)
    assert np.allclose(scale.rgb([50.0])[0], hex_rgb(SPEC_MID))
    blue, red = scale.rgb([0.0])[0], scale.rgb([200.0])[0]
    assert blue[2] > blue[0] and red[0] > red[2]  # below the spec blue, above it red
    # a tolerance of 0 still gives a scale centred on the target
    assert film_scale(50.0, 0.0).ticks[0] == [40.0, 50.0, 60.0]


def test_film_views_pick_the_sides_that_face_the_painted_area(planned):
    scene = scene_from_folder(planned)
    views = film_views(scene)
    assert views[0] == "top" and len(set(views)) == 3
    # a part painted only on its -x side: that side is among the views
    side = _sheet(0.0, 1.0)
    rot = np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])  # z -> -x
    v, n = side.vertices @ rot.T, side.normals @ rot.T
    turned = Surface(v, side.faces, n, side.area_mm2, side.thickness_um)
    from dataclasses import replace

    assert "from -x" in film_views(replace(scene, surface=turned))


def test_a_thinned_viewer_stays_within_its_limits(planned):
    scene = scene_from_folder(planned)
    limits = ViewerLimits(max_faces=2_000, max_waypoints=1_000, max_gun_axes=50)
    data, drawn = build_figure(scene, limits)
    (part,) = [t for t in data.data if t.legendgroup == "part"]
    assert len(part.i) <= 2_000 and drawn["drawn_faces"] == len(part.i) and drawn["cell_mm"] > 0
    lines = [t for t in data.data if t.legendgroup in ("strokes", "transfers")]
    assert sum(np.isfinite(np.asarray(t.x, float)).sum() for t in lines) <= 1_000 + 2 * len(scene.plan.strokes)
    axis = next(t for t in data.data if t.legendgroup == "gun axis")
    assert np.isfinite(np.asarray(axis.x, float)).sum() <= 2 * (50 + 2 * len(scene.plan.strokes))


def test_a_point_cloud_film_is_drawn_as_coloured_points(testdata, tmp_path):
    out = tmp_path / "cloud"
    part = testdata / "pointclouds" / "reach_part_normals_ascii.pcd"
    argv = ["-q", "plan", str(part), "--units", "m", "--region", "x > -200", "--simulate", "-o", str(out)]
    assert main(argv) == 0
    film = read_thickness_ply(out / "thickness.ply")
    assert len(film.faces) == 0 and len(film.points) > 10
    (trace,) = [t for t in _figure(out)[0] if t.get("legendgroup") == "part"]
    assert trace["type"] == "scatter3d" and trace["mode"] == "markers"
    assert np.array_equal(trace["marker"]["color"], film.thickness_um.astype(np.float32))
    assert np.array_equal(_points(trace), film.points.astype(np.float32))
    # the report draws each sample as a disc of its area: the film's colours cover much of the picture
    scale = film_scale(50.0, 5.0)
    pixels = _pixels(out / "report" / "film_top.png").reshape(-1, 3)
    colours = scale.rgb(film.thickness_um)
    near = np.zeros(len(pixels), bool)
    for c in np.unique(colours.round(3), axis=0):
        near |= np.abs(pixels - c).max(axis=1) < 0.02
    assert near.mean() > 0.05


def _recorder(calls: list):
    return lambda *call: calls.append(call)


def test_the_report_drawn_in_two_processes_is_the_same_bytes(planned, tmp_path):
    """The report's images shared with a helper process (``[kinematics] processes`` = 2, the default on two
    cores) are the files one process draws, byte for byte, and report.md is the same text."""
    from sprayplan import parallel
    from sprayplan.view.report import write_report_files

    if parallel.process_count(2) < 2:
        pytest.skip("the helper needs POSIX pipes")
    parallel.start_helper(2)
    assert parallel._helper.ready.wait(60)  # ready, so that it takes pictures from the start
    scene = scene_from_folder(planned)
    folders = {}
    for processes in (1, 2):
        folders[processes] = tmp_path / f"p{processes}"
        folders[processes].mkdir()
        counts: list = []
        write_report_files(str(folders[processes]), scene, progress=_recorder(counts), processes=processes)
        total = counts[-1][1]
        assert counts[-1] == (total, total) and total == len(list(folders[processes].glob("*.png")))
    names = sorted(p.name for p in folders[1].iterdir())
    assert names == sorted(p.name for p in folders[2].iterdir()) and len(names) > 5
    for name in names:
        assert (folders[1] / name).read_bytes() == (folders[2] / name).read_bytes(), name


def test_a_measuring_point_table_shows_its_interval_and_an_old_one_none():
    from sprayplan.view.summary import measured_interval

    assert measured_interval({"share_in_spec": 0.94, "share_in_spec_ci95": [0.9136, 0.9594]}) == " (95 %: 91.4-95.9 %)"
    assert measured_interval({"share_in_spec": 0.94}) == ""
    assert measured_interval({"share_in_spec_ci95": [0.9, float("nan")]}) == ""


def test_a_cell_films_open_and_recessed_surface_are_shown_and_an_old_film_shows_none():
    from sprayplan.view.summary import open_surface

    film = {
        "whole": {"share_in_spec": 0.927},
        "open": {"share_in_spec": 0.9512, "area_mm2": 11.8e6, "recess_mm": 143.0},
        "recessed": {"share_in_spec": 0.146, "area_mm2": 0.34e6},
    }
    assert open_surface(film) == (
        ", 95.1 % over the surface a gun faces square (nothing within 143 mm in front; recessed 0.34 m^2,"
        " 14.6 % in spec)"
    )
    none_recessed = {**film, "recessed": {"count": 0}}
    assert (
        open_surface(none_recessed) == ", 95.1 % over the surface a gun faces square (nothing within 143 mm in front)"
    )
    both = {**film, "open_reached": {"share_in_spec": 0.9613, "area_mm2": 11.3e6}}
    assert open_surface(both) == (
        ", 95.1 % over the surface a gun faces square (nothing within 143 mm in front; recessed 0.34 m^2,"
        " 14.6 % in spec), 96.1 % over the open surface some robot reaches"
    )
    assert open_surface({**both, "open_reached": {"share_in_spec": None}}) == open_surface(film)
    assert open_surface({"whole": {"share_in_spec": 0.9}}) == ""
    from sprayplan.view.summary import out_of_spec_causes

    causes = {"unreached": 0.0215, "recessed": 0.0096, "bare": 0.0033, "thin": 0.0204, "thick": 0.0172, "rule": "x"}
    assert out_of_spec_causes({**film, "out_of_spec": causes}) == (
        "out of spec: unreached 2.1 %, recessed 1.0 %, bare 0.3 %, thin 2.0 %, thick 1.7 % of the painted area"
    )
    assert out_of_spec_causes(film) == ""
    assert out_of_spec_causes({"out_of_spec": {**causes, "thin": None}}) == ""
    assert open_surface({**film, "open": {"share_in_spec": float("nan"), "recess_mm": 143.0}}) == ""
