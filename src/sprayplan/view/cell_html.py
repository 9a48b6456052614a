"""A cell plan's 3D viewer (``sprayplan plan --cell``): ``cell.html``, one self-contained page (plotly.js embedded).

Layers (legend entries; a click switches one on or off):

- ``film``: the painted surface coloured by the predicted dry film (the gantry viewer's scale:
  ``view.colours.film_scale``), or grey without a film;
- ``areas: <robot>``: the faces each robot paints, in its colour (``view.colours.ROBOT_COLOURS``, as
  ``areas.png``); hidden at first (a click on the legend shows them), and ``unreached`` faces in grey;
- ``<robot> strokes``: the gun tip's path of each robot's spray strokes (hover: robot, stroke, waypoint, area),
  its transfers grey and dashed;
- ``<robot> base``: the robot's base (and its track as a line), named;
- ``unreached`` / ``in collision``: waypoints the plan does not reach, and (``--collisions``) those still in
  collision.

What is drawn is thinned (``view.decimate``: at most :data:`MAX_FACES` triangles a layer, about
:data:`MAX_WAYPOINTS` waypoints in all); what was computed is not changed. The page's JSON summary
(``<script id="sprayplan-summary">``) says what was drawn, for the tests.
"""

from __future__ import annotations

import html
import json

import numpy as np

from sprayplan.view.colours import GREY, ROBOT_COLOURS, film_scale
from sprayplan.view.decimate import thin_indices, thin_surface
from sprayplan.view.scene import Surface, vertex_areas, vertex_normals
from sprayplan.view.summary import measured_interval, open_surface, out_of_spec_causes

PLOT_ID = "sprayplan-cell"
MAX_FACES = 60_000
MAX_WAYPOINTS = 60_000


def _f4(a) -> np.ndarray:
    return np.asarray(a, dtype=np.float32)


def _surface(vertices, faces, thickness=None) -> Surface:
    return Surface(vertices, faces, vertex_normals(vertices, faces), vertex_areas(vertices, faces), thickness)


def _sub_mesh(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    used = np.unique(faces)
    remap = np.full(len(vertices), -1)
    remap[used] = np.arange(len(used))
    return vertices[used], remap[faces]


def _mesh(go, s: Surface, **kw):
    return go.Mesh3d(
        x=_f4(s.vertices[:, 0]), y=_f4(s.vertices[:, 1]), z=_f4(s.vertices[:, 2]),
        i=s.faces[:, 0].astype(np.int32), j=s.faces[:, 1].astype(np.int32), k=s.faces[:, 2].astype(np.int32),
        lighting=dict(ambient=0.8, diffuse=0.35, specular=0.02, roughness=0.9, fresnel=0.02), **kw,
    )  # fmt: skip


def _film_trace(go, plan, target_um: float, tolerance_um: float, drawn: dict):
    part = plan.part
    thickness = None
    if plan.film is not None:
        from scipy.spatial import cKDTree

        thickness = plan.film.thickness_um[cKDTree(plan.film.points).query(part.vertices)[1]]
    thinned = thin_surface(_surface(part.vertices, part.faces, thickness), MAX_FACES)
    s = thinned.surface
    drawn.update(faces=len(part.faces), drawn_faces=len(s.faces), cell_mm=thinned.cell_mm)
    common = dict(name="film (um)" if thickness is not None else "part (no film)", legendgroup="film",
                  showlegend=True)  # fmt: skip
    if thickness is None:
        return _mesh(go, s, color=GREY, hoverinfo="skip", **common)
    scale = film_scale(target_um, tolerance_um)
    values, labels = scale.ticks
    return _mesh(
        go, s, intensity=_f4(s.thickness_um), intensitymode="vertex", colorscale=scale.plotly(), cmin=scale.cmin,
        cmax=scale.cmax, hovertemplate="film %{intensity:.1f} um<extra></extra>",
        colorbar=dict(title=dict(text=f"dry film, um<br>spec {target_um:g} +- {tolerance_um:g}", side="top"),
                      tickvals=values, ticktext=labels, len=0.75, x=1.0),
        **common,
    )  # fmt: skip


def _area_traces(go, plan, colours) -> list:
    if plan.assignment is None:
        return []
    part, fr = plan.part, plan.assignment.face_robot
    out = []
    groups = [(i, r.name, colours[i % len(colours)]) for i, r in enumerate(plan.cell.robots)]
    for i, name, colour in [*groups, (-1, "unreached", "#b0b0b0")]:
        faces = part.faces[fr == i]
        if not len(faces):
            continue
        v, f = _sub_mesh(part.vertices, faces)
        s = thin_surface(_surface(v, f), MAX_FACES // max(1, len(groups))).surface
        out.append(_mesh(go, s, color=colour, name=f"areas: {name}", legendgroup=f"areas {name}",
                         visible="legendonly", showlegend=True, hoverinfo="name", flatshading=True))  # fmt: skip
    return out


def _stroke_traces(go, plan, colours, drawn: dict) -> list:
    out = []
    lengths = [len(s) for r in plan.robots for s in r.strokes]
    keep = iter(thin_indices(lengths, MAX_WAYPOINTS))
    drawn.update(waypoints=int(sum(lengths)), drawn_waypoints=0)
    flags = {"unreached": [], "in collision": []}
    for i, work in enumerate(plan.robots):
        colour = colours[i % len(colours)]
        spray, transfer, text = [], [], []
        at = 0
        for k, s in enumerate(work.strokes):
            idx = next(keep)
            pts = s.tcp[idx]
            drawn["drawn_waypoints"] += len(idx)
            target = spray if s.spray_on else transfer
            target.append(np.vstack([pts, np.full((1, 3), np.nan)]))
            if s.spray_on:
                text += [f"{work.name} stroke {k} waypoint {j} area {int(work.area[k])}" for j in idx] + [""]
            reach = work.reachable[at : at + len(s)]
            flags["unreached"] += [(work.name, k, j, s.tcp[j]) for j in np.flatnonzero(~reach)]
            if work.collides is not None:
                hit = work.collides[at : at + len(s)] & reach
                flags["in collision"] += [(work.name, k, j, s.tcp[j]) for j in np.flatnonzero(hit)]
            at += len(s)
        if spray:
            p = np.vstack(spray)
            out.append(go.Scatter3d(x=_f4(p[:, 0]), y=_f4(p[:, 1]), z=_f4(p[:, 2]), mode="lines",
                                    line=dict(color=colour, width=3), name=f"{work.name} strokes",
                                    legendgroup=work.name, text=text, hovertemplate="%{text}<extra></extra>"))  # fmt: skip
        if transfer:
            p = np.vstack(transfer)
            out.append(go.Scatter3d(x=_f4(p[:, 0]), y=_f4(p[:, 1]), z=_f4(p[:, 2]), mode="lines",
                                    line=dict(color=GREY, width=2, dash="dash"), name=f"{work.name} transfers",
                                    legendgroup=work.name, hoverinfo="skip", visible="legendonly"))  # fmt: skip
    for name, colour, symbol in (("unreached", "#7f7f7f", "circle"), ("in collision", "#d62728", "x")):
        found = flags[name]
        drawn[name.replace(" ", "_")] = len(found)
        if found:
            p = np.array([f[3] for f in found])
            label = [f"{name}: {r} stroke {k} waypoint {j}" for r, k, j, _ in found]
            out.append(go.Scatter3d(x=_f4(p[:, 0]), y=_f4(p[:, 1]), z=_f4(p[:, 2]), mode="markers",
                                    marker=dict(size=3, color=colour, symbol=symbol), name=f"{name} ({len(found)})",
                                    text=label, hovertemplate="%{text}<extra></extra>"))  # fmt: skip
    return out


def _base_traces(go, plan, colours) -> list:
    out = []
    for i, r in enumerate(plan.cell.robots):
        colour = colours[i % len(colours)]
        path = r.base_path_mm()
        ends = path[[0, -1]]
        out.append(go.Scatter3d(x=_f4(ends[:, 0]), y=_f4(ends[:, 1]), z=_f4(ends[:, 2]),
                                mode="lines+markers+text" if len(path) > 1 else "markers+text",
                                line=dict(color=colour, width=8), marker=dict(size=6, color=colour, symbol="square"),
                                text=[r.name, ""][: len(ends)], textposition="top center",
                                name=f"{r.name} base{' and track' if r.track is not None else ''} ({r.model})",
                                legendgroup=r.name, hovertemplate=f"{html.escape(r.name)}: {html.escape(r.model)}"
                                "<extra></extra>"))  # fmt: skip
    return out


def cell_figure(plan, target_um: float, tolerance_um: float):
    """The plotly figure of a cell plan (module docstring) and what was drawn."""
    import plotly.graph_objects as go

    drawn: dict = {}
    traces = [_film_trace(go, plan, target_um, tolerance_um, drawn), *_area_traces(go, plan, ROBOT_COLOURS)]
    traces += _stroke_traces(go, plan, ROBOT_COLOURS, drawn) + _base_traces(go, plan, ROBOT_COLOURS)
    figure = go.Figure(traces)
    figure.update_layout(
        scene=dict(aspectmode="data", xaxis_title="x (mm)", yaxis_title="y (mm)", zaxis_title="z (mm)"),
        margin=dict(l=0, r=0, t=10, b=0),
        legend=dict(itemsizing="constant", x=0.0, y=1.0, xanchor="left", bgcolor="rgba(255,255,255,0.7)"),
        uirevision="cell",
    )
    return figure, drawn


_STYLE = """
body { margin: 0; font-family: system-ui, -apple-system, "Segoe UI", Roboto, Arial, sans-serif; color: #222; }
header { padding: 8px 14px 4px; border-bottom: 1px solid #ddd; }
h1 { font-size: 18px; margin: 0 0 6px; }
p { font-size: 13px; margin: 2px 0; }
.drawn { font-size: 12px; color: #666; }
"""


def _name(plan) -> str:
    import os

    name = plan.name or (plan.part.name if plan.part is not None else "")
    return os.path.basename(name) or "cell plan"


def _header(plan, drawn: dict) -> str:
    report = plan.report
    lines = []
    robots = report.get("robots", {})
    if robots:
        lines.append("; ".join(
            f"{name}: {r['strokes']} strokes, {r['waypoints']} waypoints ({r['unreached_waypoints']} unreached), "
            f"{r['cycle_time_s']:.0f} s" for name, r in robots.items()
        ))  # fmt: skip
    film = report.get("film")
    if film:
        whole, points = film["whole"], film["report"].get("measuring_points", {})
        lines.append(
            f"film over the whole body: mean {whole['mean_um']:.1f} um, {100 * whole['share_in_spec']:.1f} % in spec"
            f"{open_surface(film)}; "
            f"{points.get('count', 0)} measuring points: {100 * points.get('share_in_spec', 0.0):.1f} % in spec"
            f"{measured_interval(points)}"
        )
        if out_of_spec_causes(film):
            lines.append(out_of_spec_causes(film))
    if "cycle_time_s" in report:
        lines.append(f"cycle {report['cycle_time_s']:.0f} s ({report.get('cycle_time_rule', '')})")
    thinned = []
    if drawn.get("cell_mm"):
        thinned.append(f"drawn: {drawn['drawn_faces']:,} of {drawn['faces']:,} triangles")
    if drawn.get("drawn_waypoints", 0) < drawn.get("waypoints", 0):
        thinned.append(f"{drawn['drawn_waypoints']:,} of {drawn['waypoints']:,} waypoints")
    body = "".join(f"<p>{html.escape(line)}</p>" for line in lines)
    note = f"<p class='drawn'>{html.escape('; '.join(thinned))}</p>" if thinned else ""
    return (
        f"<header><h1>sprayplan: {html.escape(_name(plan))} in cell {html.escape(plan.cell.name)}</h1>"
        f"{body}{note}<p class='drawn'>A click on a legend entry switches it on and off (the areas of each robot "
        "are off at first); drag to turn, scroll to zoom; hover a stroke for its robot, stroke, waypoint and area."
        "</p></header>"
    )


def cell_viewer_html(plan, target_um: float, tolerance_um: float) -> tuple[str, dict]:
    """``cell.html``'s text and what was drawn."""
    figure, drawn = cell_figure(plan, target_um, tolerance_um)
    plot = figure.to_html(
        full_html=False, include_plotlyjs=True, div_id=PLOT_ID, default_width="100%", default_height="80vh",
        config={"displaylogo": False, "responsive": True, "scrollZoom": True},
    )  # fmt: skip
    summary = json.dumps({"name": _name(plan), "cell": plan.cell.name, "drawn": drawn}, default=float)
    page = (
        "<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
        f"<title>sprayplan: {html.escape(_name(plan))}</title><style>{_STYLE}</style></head><body>"
        f"{_header(plan, drawn)}{plot}"
        f"<script type='application/json' id='sprayplan-summary'>{html.escape(summary, quote=False)}</script>"
        "</body></html>\n"
    )
    return page, drawn
