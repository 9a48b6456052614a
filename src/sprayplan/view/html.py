"""The plan's 3D viewer: one self-contained HTML file (plotly, with plotly.js embedded: no network needed).

Layers (each a legend entry, or a group of them, that a click switches on and off):

- ``part``: the part coloured by the predicted dry film on :func:`view.colours.film_scale` (target and
  tolerance marked on the colour bar), or grey without a film;
- ``spray strokes``: the gun tip's path, one colour per gantry station (touch-ups dotted), with hover text
  (station, stroke, waypoint, tip speed, dwell factor);
- ``transfers``: the spray-off moves, grey and dashed;
- ``gun axis``: short segments from the gun tip to the surface at a thinned set of spray waypoints;
- ``stations``: the gantry platform positions (numbered in visiting order) and their working circles;
- ``gantry tour``: home -> stations -> home;
- ``flagged``: waypoints the arm cannot reach, reaches only within the tolerance (SQP), or reaches with a
  change of IK branch, and points no station reaches, each with the reason on hover.

What is drawn is thinned (``view.decimate``); what was computed is not changed. See docs/viewer.md.
"""

from __future__ import annotations

import html
import json
from dataclasses import dataclass

import numpy as np

from sprayplan.view.colours import GREY, STATION_COLOURS, film_scale
from sprayplan.view.decimate import thin_indices, thin_surface
from sprayplan.view.scene import Scene
from sprayplan.view.summary import summary_rows

#: The div the figure is drawn in.
PLOT_ID = "sprayplan-plan"


@dataclass(frozen=True)
class ViewerLimits:
    """How much the viewer draws at most (it thins beyond: ``view.decimate``).

    Attributes
    ----------
    max_faces : int
        Triangles of the part (or points of a point cloud).
    max_waypoints : int
        Waypoints of the strokes and transfers, drawn as line vertices.
    max_gun_axes : int
        Gun-axis segments.
    """

    max_faces: int = 80_000
    max_waypoints: int = 120_000
    max_gun_axes: int = 1_500


def _f4(a) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float32)


def _joined(chunks: list[np.ndarray], width: int) -> np.ndarray:
    """Polylines joined into one array with a NaN row between them (plotly breaks a line at NaN)."""
    if not chunks:
        return np.zeros((0, width), np.float32)
    gap = np.full((1, width), np.nan)
    parts = []
    for c in chunks:
        parts += [c, gap]
    return _f4(np.vstack(parts[:-1]))


def _stroke_slices(plan):
    """Per stroke of the plan, in order: (station_plan, stroke_index, stroke, slice into the station's arrays)."""
    for st in plan.stations:
        start = 0
        for i, s in enumerate(st.strokes):
            yield st, i, s, slice(start, start + len(s))
            start += len(s)


def waypoint_table(scene: Scene):
    """Per waypoint of the plan, in order: station position (visit order), station number, stroke index,
    waypoint index within the stroke, tip speed (mm/s), dwell, and the stroke object; as a list of
    (station_plan, stroke_index, stroke, slice into the station's arrays, speeds)."""
    from sprayplan.export.plan_json import tip_speeds

    return [(st, i, s, sl, tip_speeds(s, scene.job)) for st, i, s, sl in _stroke_slices(scene.plan)]


def flagged_waypoints(scene: Scene) -> dict[str, tuple[np.ndarray, list[str]]]:
    """The waypoints to warn about, by reason: ``unreachable``, ``approximate`` (SQP within the tolerance),
    ``branch change``, ``collision`` (the waypoint or the motion into it, after repairs) and ``unassigned``
    (points no station reaches): (positions (k, 3), hover texts)."""
    kin = scene.job.kinematics
    kinds = ("unreachable", "approximate", "branch change", "collision")
    out: dict[str, tuple[list, list]] = {k: ([], []) for k in kinds}  # (blocks of positions, texts)
    for st, i, s, sl in _stroke_slices(scene.plan):
        reach = st.reachable[sl]
        method = st.method[sl]
        err = st.position_error_mm[sl]
        axis = st.axis_error_deg[sl]
        flip = st.branch_change[sl]
        where = f"station {st.index}, stroke {i} ({s.kind}), waypoint "
        index = np.flatnonzero(~reach)
        if len(index):
            out["unreachable"][0].append(s.tcp[index])
            out["unreachable"][1].extend(
                [where + f"{j}: unreachable (no IK solution within the limits)" for j in index.tolist()]
            )
        approx = reach & (method == "sqp") & ((np.nan_to_num(err) > 0.01) | (np.nan_to_num(axis) > 0.01))
        index = np.flatnonzero(approx)
        if len(index):
            out["approximate"][0].append(s.tcp[index])
            out["approximate"][1].extend(
                [
                    where + f"{j}: reached by SQP only within the tolerance: position error {e:.2f} mm "
                    f"(<= {kin.position_tol_mm:g}), axis error {a:.2f} deg (<= {kin.axis_tol_deg:g})"
                    for j, e, a in zip(index.tolist(), err[index].tolist(), axis[index].tolist())
                ]
            )
        index = np.flatnonzero(reach & flip)
        if len(index):
            out["branch change"][0].append(s.tcp[index])
            out["branch change"][1].extend(
                [where + f"{j}: the arm changes its IK branch here (a flip)" for j in index.tolist()]
            )
        hit, moving = st.collision[sl], st.motion_collision[sl]
        index = np.flatnonzero(reach & (hit | moving))
        if len(index):
            out["collision"][0].append(s.tcp[index])
            texts = out["collision"][1]
            for j in index:
                what = []
                if hit[j]:
                    what.append(f"{st.collision_with[sl][j]} at {st.collision_distance_mm[sl][j]:.1f} mm")
                if moving[j]:
                    what.append("the motion into it")
                texts.append(where + f"{j}: in collision, no repair freed it: " + "; ".join(what))
    result = {
        k: (np.concatenate(v[0]).reshape(-1, 3) if v[0] else np.array([]).reshape(-1, 3), v[1]) for k, v in out.items()
    }
    un = scene.plan.unassigned
    result["unassigned"] = (
        np.asarray(un).reshape(-1, 3),
        ["no gantry station reaches this point: not painted"] * len(un),
    )
    return result


FLAG_STYLE = {
    "unreachable": ("#d62728", "x", "unreachable waypoints"),
    "approximate": ("#ff7f0e", "diamond", "waypoints reached only within the tolerance (SQP)"),
    "branch change": ("#e377c2", "circle", "waypoints where the arm changes IK branch"),
    "collision": ("#8c564b", "square", "waypoints in collision (closer than the clearance, or below the floor)"),
    "unassigned": ("#000000", "cross", "points no station reaches"),
}


def _part_traces(scene: Scene, limits: ViewerLimits, go) -> tuple[list, dict]:
    surface = scene.surface
    if surface is None:
        return [], {"drawn_faces": 0, "faces": 0, "cell_mm": 0.0}
    thinned = thin_surface(surface, limits.max_faces)
    s = thinned.surface
    info = {
        "faces": thinned.source_faces,
        "vertices": thinned.source_vertices,
        "drawn_faces": len(s.faces),
        "drawn_vertices": len(s.vertices),
        "cell_mm": thinned.cell_mm,
    }
    film = s.thickness_um is not None
    common = dict(name="part: dry film (um)" if film else "part (no film)", legendgroup="part", showlegend=True)
    if film:
        scale = film_scale(scene.target_um, scene.tolerance_um)
        values, labels = scale.ticks
        colour = dict(
            colorscale=scale.plotly(),
            cmin=scale.cmin,
            cmax=scale.cmax,
            colorbar=dict(
                title=dict(text=f"dry film, um<br>spec {scene.target_um:g} +- {scene.tolerance_um:g}", side="top"),
                tickvals=values,
                ticktext=labels,
                len=0.75,
                x=1.0,
            ),
        )
        hover = "film %{intensity:.1f} um<extra></extra>"
    if len(s.faces):
        mesh = dict(
            x=_f4(s.vertices[:, 0]),
            y=_f4(s.vertices[:, 1]),
            z=_f4(s.vertices[:, 2]),
            i=s.faces[:, 0].astype(np.int32),
            j=s.faces[:, 1].astype(np.int32),
            k=s.faces[:, 2].astype(np.int32),
            lighting=dict(ambient=0.8, diffuse=0.35, specular=0.02, roughness=0.9, fresnel=0.02),
            flatshading=False,
            **common,
        )
        if film:
            trace = go.Mesh3d(
                intensity=_f4(s.thickness_um), intensitymode="vertex", hovertemplate=hover, **colour, **mesh
            )
        else:
            trace = go.Mesh3d(color=GREY, hoverinfo="skip", **mesh)
    else:
        marker = dict(size=float(np.clip(12.0 - 2.0 * np.log10(max(len(s.vertices), 1)), 2.0, 8.0)))
        if film:
            marker.update(color=_f4(s.thickness_um), **colour)
        else:
            marker.update(color=GREY)
        trace = go.Scatter3d(
            x=_f4(s.vertices[:, 0]),
            y=_f4(s.vertices[:, 1]),
            z=_f4(s.vertices[:, 2]),
            mode="markers",
            marker=marker,
            hovertemplate="film %{marker.color:.1f} um<extra></extra>" if film else None,
            hoverinfo=None if film else "skip",
            **common,
        )
    return [trace], info


def _stroke_traces(scene: Scene, limits: ViewerLimits, go) -> tuple[list, dict]:
    rows = waypoint_table(scene)
    keep = thin_indices([len(r[2]) for r in rows], limits.max_waypoints)
    by_station: dict[tuple, list] = {}
    order = {st.index: place for place, st in enumerate(scene.plan.stations)}
    timing = scene.timing
    place_of = {id(st): place for place, st in enumerate(scene.plan.stations)}
    for (st, i, s, sl, speed), idx in zip(rows, keep):
        columns = [s.tcp[idx], np.full(len(idx), st.index), np.full(len(idx), i), idx, speed[idx], s.dwell[idx]]
        if timing is not None:  # the tip speed the robot makes and the time stamp
            place = place_of[id(st)]
            columns += [timing.speed_mm_s[place][sl][idx], timing.t_s[place][sl][idx]]
        data = np.column_stack(columns)
        kind = s.kind
        by_station.setdefault((kind, st.index), []).append(data)
    template = (
        "station %{customdata[0]:d}, stroke %{customdata[1]:d}, waypoint %{customdata[2]:d}<br>"
        "tip speed %{customdata[3]:.0f} mm/s, dwell %{customdata[4]:.3f}"
    )
    if timing is not None:
        template += "<br>achievable %{customdata[5]:.0f} mm/s, t = %{customdata[6]:.2f} s"
    template += "<extra>%{fullData.name}</extra>"
    width = 10 if timing is not None else 8
    traces = []
    transfers = []
    for (kind, station), chunks in sorted(by_station.items(), key=lambda kv: (kv[0][0] != "spray", order[kv[0][1]])):
        if kind == "transfer":
            transfers += chunks
            continue
        data = _joined(chunks, width)
        colour = STATION_COLOURS[order[station] % len(STATION_COLOURS)]
        traces.append(
            go.Scatter3d(
                x=data[:, 0],
                y=data[:, 1],
                z=data[:, 2],
                customdata=data[:, 3:],
                mode="lines",
                line=dict(color=colour, width=2 if kind == "spray" else 4, dash="solid" if kind == "spray" else "dot"),
                name=f"stop {order[station] + 1} (station {station})" + ("" if kind == "spray" else " touch-ups"),
                legendgroup="strokes",
                legendgrouptitle_text="spray strokes (by station)",
                hovertemplate=template,
            )
        )
    if transfers:
        data = _joined(transfers, width)
        traces.append(
            go.Scatter3d(
                x=data[:, 0],
                y=data[:, 1],
                z=data[:, 2],
                customdata=data[:, 3:],
                mode="lines",
                line=dict(color="#999999", width=2, dash="dash"),
                opacity=0.6,
                name="transfers (gun off)",
                legendgroup="transfers",
                hovertemplate=template,
            )
        )
    drawn = sum(len(k) for k in keep)
    return traces, {"waypoints": sum(len(r[2]) for r in rows), "drawn_waypoints": drawn}


def _gun_axis_trace(scene: Scene, limits: ViewerLimits, go) -> list:
    spray = [s for st in scene.plan.stations for s in st.strokes if s.spray_on]
    if not spray:
        return []
    keep = thin_indices([len(s) for s in spray], limits.max_gun_axes)
    segments = [np.vstack([s.tcp[j], s.points[j]]) for s, idx in zip(spray, keep) for j in idx]
    data = _joined(segments, 3)
    return [
        go.Scatter3d(
            x=data[:, 0],
            y=data[:, 1],
            z=data[:, 2],
            mode="lines",
            line=dict(color="#404040", width=2),
            name="gun axis (tip to surface)",
            legendgroup="gun axis",
            visible="legendonly",
            hoverinfo="skip",
        )
    ]


def _station_traces(scene: Scene, go) -> list:
    plan = scene.plan
    if not plan.stations:
        return []
    platforms = np.array([st.platform_mm for st in plan.stations])
    t = np.linspace(0.0, 2.0 * np.pi, 73)
    r = scene.working_radius_mm
    circles = [np.column_stack([p[0] + r * np.cos(t), p[1] + r * np.sin(t), np.full(len(t), p[2])]) for p in platforms]
    circle = _joined(circles, 3)
    n_strokes = [sum(1 for s in st.strokes if s.spray_on) for st in plan.stations]
    hover = [
        f"station {st.index}, stop {k + 1} of {len(platforms)}<br>platform ({p[0]:.0f}, {p[1]:.0f}, {p[2]:.0f}) mm"
        f"<br>{n} spray strokes"
        for k, (st, p, n) in enumerate(zip(plan.stations, platforms, n_strokes))
    ]
    tour = _f4(np.vstack([plan.home_mm, platforms, plan.home_mm]))
    return [
        go.Scatter3d(
            x=_f4(platforms[:, 0]),
            y=_f4(platforms[:, 1]),
            z=_f4(platforms[:, 2]),
            mode="markers+text",
            marker=dict(size=6, color=[STATION_COLOURS[k % len(STATION_COLOURS)] for k in range(len(platforms))]),
            text=[str(k + 1) for k in range(len(platforms))],
            textposition="top center",
            hovertext=hover,
            hoverinfo="text",
            name="stations (stop number)",
            legendgroup="stations",
            legendgrouptitle_text="gantry",
        ),
        go.Scatter3d(
            x=circle[:, 0],
            y=circle[:, 1],
            z=circle[:, 2],
            mode="lines",
            line=dict(color="#7f7f7f", width=2),
            name=f"working circles (r {r:.0f} mm)",
            legendgroup="stations",
            hoverinfo="skip",
        ),
        go.Scatter3d(
            x=tour[:, 0],
            y=tour[:, 1],
            z=tour[:, 2],
            mode="lines+markers",
            line=dict(color="#2ca02c", width=3),
            marker=dict(size=[8] + [2] * len(platforms) + [8], color="#2ca02c", symbol="square"),
            hovertext=["home"] + [f"stop {k + 1}" for k in range(len(platforms))] + ["home"],
            hoverinfo="text",
            name="gantry tour (home, stops, home)",
            legendgroup="tour",
        ),
    ]


def _flag_traces(scene: Scene, go) -> tuple[list, dict]:
    traces, counts = [], {}
    for reason, (where, text) in flagged_waypoints(scene).items():
        counts[reason] = len(where)
        if not len(where):
            continue
        colour, symbol, label = FLAG_STYLE[reason]
        traces.append(
            go.Scatter3d(
                x=_f4(where[:, 0]),
                y=_f4(where[:, 1]),
                z=_f4(where[:, 2]),
                mode="markers",
                marker=dict(size=4 if reason == "unreachable" else 2, color=colour, symbol=symbol),
                hovertext=text,
                hoverinfo="text",
                name=f"{label} ({len(where)})",
                legendgroup="flagged",
                legendgrouptitle_text="flagged",
            )
        )
    return traces, counts


def _camera(traces) -> tuple[dict, dict]:
    """The scene's aspect ratio (the data's true proportions, the longest axis 1) and a camera that sees all of
    it from the front left, above."""
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for t in traces:
        if getattr(t, "x", None) is None:
            continue
        xyz = np.column_stack([np.asarray(getattr(t, k), float) for k in "xyz"])
        xyz = xyz[np.isfinite(xyz).all(axis=1)]
        if len(xyz):
            lo, hi = np.minimum(lo, xyz.min(axis=0)), np.maximum(hi, xyz.max(axis=0))
    span = np.where(np.isfinite(hi - lo) & (hi > lo), hi - lo, 1.0)
    ratio = span / span.max()
    direction = np.array([-0.55, -0.65, 0.52])
    # nearer for a long, thin part (a hull), farther for a squat one (a roof and its gantry above it)
    eye = (1.35 + 0.6 * float(np.sort(ratio)[1])) * direction / np.linalg.norm(direction)
    return dict(zip("xyz", (float(r) for r in ratio))), dict(zip("xyz", (float(e) for e in eye)))


#: The layer buttons above the view: (label, legend groups switched together).
LAYERS = (
    ("part", ("part",)),
    ("strokes", ("strokes",)),
    ("transfers", ("transfers",)),
    ("gun axis", ("gun axis",)),
    ("gantry", ("stations", "tour")),
    ("flagged", ("flagged",)),
)


def _layer_buttons(traces) -> dict:
    """One toggle button per layer: a click hides all of its traces, the next click shows them again (the
    gun axis, hidden at first, the other way round)."""
    buttons = []
    for label, groups in LAYERS:
        index = [i for i, t in enumerate(traces) if t.legendgroup in groups]
        if not index:
            continue
        shown, hidden = [True] * len(index), ["legendonly"] * len(index)  # hidden: still in the legend
        first, second = (hidden, shown) if traces[index[0]].visible is None else (shown, hidden)
        buttons.append(
            dict(label=label, method="restyle", args=[{"visible": first}, index], args2=[{"visible": second}, index])
        )
    return dict(
        type="buttons",
        direction="right",
        showactive=False,
        x=0.2,
        xanchor="left",
        y=1.0,
        yanchor="top",
        buttons=buttons,
    )


def build_figure(scene: Scene, limits: ViewerLimits | None = None):
    """The plotly figure of a scene, and what was drawn of it (counts, for the summary and the tests)."""
    import plotly.graph_objects as go

    limits = limits or ViewerLimits()
    part, part_info = _part_traces(scene, limits, go)
    strokes, stroke_info = _stroke_traces(scene, limits, go)
    flags, flag_counts = _flag_traces(scene, go)
    traces = part + strokes + _gun_axis_trace(scene, limits, go) + _station_traces(scene, go) + flags
    figure = go.Figure(traces)
    ratio, eye = _camera(traces)
    axis = dict(showbackground=False, gridcolor="#e5e5e5", zerolinecolor="#cccccc")
    figure.update_layout(
        scene=dict(
            domain=dict(x=[0.2, 0.94], y=[0.0, 1.0]),  # the legend on the left, the colour bar on the right
            aspectmode="manual",  # true proportions (as "data"), and a camera far enough for the longest axis
            aspectratio=ratio,
            xaxis=dict(title="x (mm)", **axis),
            yaxis=dict(title="y (mm)", **axis),
            zaxis=dict(title="z (mm)", **axis),
            camera=dict(eye=eye),
        ),
        legend=dict(groupclick="toggleitem", itemsizing="constant", x=0.0, y=1.0, bgcolor="rgba(255,255,255,0.8)"),
        margin=dict(l=0, r=0, t=0, b=0),
        paper_bgcolor="white",
        uirevision="sprayplan",
        updatemenus=[_layer_buttons(traces)],
    )
    drawn = {**part_info, **stroke_info, "flagged": flag_counts}
    return figure, drawn


_STYLE = """
body { margin: 0; font-family: system-ui, -apple-system, "Segoe UI", Roboto, Arial, sans-serif; color: #222; }
header { padding: 8px 14px 4px; border-bottom: 1px solid #ddd; }
h1 { font-size: 18px; margin: 0 0 6px; }
.tables { display: flex; flex-wrap: wrap; gap: 4px 28px; }
table { border-collapse: collapse; font-size: 13px; }
th { text-align: left; font-weight: 600; padding: 0 0 2px; }
td { padding: 0 10px 0 0; white-space: nowrap; }
td.v { font-variant-numeric: tabular-nums; }
.notes { font-size: 13px; color: #8a4b00; margin: 4px 0 0; }
.drawn { font-size: 12px; color: #666; margin: 4px 0 0; }
"""


def _header(scene: Scene, drawn: dict) -> str:
    tables = []
    for title, rows in summary_rows(scene):
        body = "".join(f"<tr><td>{html.escape(k)}</td><td class='v'>{html.escape(v)}</td></tr>" for k, v in rows)
        tables.append(f"<table><tr><th colspan='2'>{html.escape(title)}</th></tr>{body}</table>")
    notes = "".join(f"<p class='notes'>{html.escape(n)}</p>" for n in scene.notes)
    thinned = []
    if drawn.get("cell_mm"):
        thinned.append(
            f"drawn: {drawn['drawn_faces']:,} of {drawn['faces']:,} triangles (vertices merged in {drawn['cell_mm']:.1f} mm cells)"
        )
    if drawn.get("drawn_waypoints", 0) < drawn.get("waypoints", 0):
        thinned.append(f"{drawn['drawn_waypoints']:,} of {drawn['waypoints']:,} waypoints")
    drawn_line = (
        f"<p class='drawn'>{html.escape('; '.join(thinned))} (the figures above are of the whole plan)</p>"
        if thinned
        else ""
    )
    return (
        f"<header><h1>sprayplan: {html.escape(scene.name or 'plan')}</h1>"
        f"<div class='tables'>{''.join(tables)}</div>{notes}{drawn_line}"
        "<p class='drawn'>The buttons above the view switch a whole layer on and off, a click on a legend entry "
        "one trace (a station's strokes, say); "
        "drag to turn, scroll to zoom; hover a stroke for its station, stroke, waypoint, speed and dwell.</p></header>"
    )


def viewer_html(scene: Scene, limits: ViewerLimits | None = None) -> tuple[str, dict]:
    """The viewer as one HTML page (plotly.js embedded), and what was drawn (:func:`build_figure`)."""
    figure, drawn = build_figure(scene, limits)
    plot = figure.to_html(
        full_html=False,
        include_plotlyjs=True,
        div_id=PLOT_ID,
        default_width="100%",
        default_height="76vh",
        config={"displaylogo": False, "responsive": True, "scrollZoom": True},
    )
    summary = json.dumps({"name": scene.name, "totals": scene.totals, "drawn": drawn}, default=float)
    page = (
        "<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
        f"<title>sprayplan: {html.escape(scene.name or 'plan')}</title><style>{_STYLE}</style></head><body>"
        f"{_header(scene, drawn)}{plot}"
        f"<script type='application/json' id='sprayplan-summary'>{html.escape(summary, quote=False)}</script>"
        "</body></html>\n"
    )
    return page, drawn


def write_viewer(path, scene: Scene, limits: ViewerLimits | None = None) -> dict:
    """Write the viewer to ``path`` atomically; returns what was drawn."""
    from sprayplan.export.files import atomic_output

    page, drawn = viewer_html(scene, limits)
    with atomic_output(path, "w", encoding="utf-8") as handle:
        handle.write(page)
    return drawn


def read_viewer_figure(page: str, plot_id: str = PLOT_ID) -> tuple[list, dict]:
    """The figure a viewer page draws: its traces and layout as plotly.js gets them, with every typed array
    (plotly's ``{"dtype", "bdata", "shape"}``) decoded into a numpy array. For checks of a written viewer;
    ``plot_id`` the plot's div (``view.cell_html.PLOT_ID`` for a cell plan's).

    Raises
    ------
    ValueError
        The page holds no ``Plotly.newPlot`` call for the viewer's plot.
    """
    import re

    found = re.search(r'Plotly\.newPlot\(\s*"' + re.escape(plot_id) + r'",\s*', page)
    if found is None:
        raise ValueError("no Plotly.newPlot call for the viewer's plot")
    start = found.end()
    decoder = json.JSONDecoder()
    data, end = decoder.raw_decode(page, start)
    rest = page[end:].lstrip()
    if not rest.startswith(","):
        raise ValueError("the viewer's Plotly.newPlot call has no layout")
    layout, _ = decoder.raw_decode(rest[1:].lstrip())
    return _decoded(data), _decoded(layout)


_DTYPES = {"f4": "<f4", "f8": "<f8", "i1": "i1", "u1": "u1", "i2": "<i2", "u2": "<u2", "i4": "<i4", "u4": "<u4"}


def _decoded(value):
    import base64

    if isinstance(value, dict):
        if set(value) >= {"dtype", "bdata"} and value["dtype"] in _DTYPES:
            array = np.frombuffer(base64.b64decode(value["bdata"]), _DTYPES[value["dtype"]])
            if value.get("shape"):
                array = array.reshape([int(n) for n in str(value["shape"]).split(",")])
            return array
        return {k: _decoded(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_decoded(v) for v in value]
    return value
