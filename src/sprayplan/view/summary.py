"""The summary of a plan as a person reads it (the viewer's panel and report.md's tables): counts from the
plan itself, lengths and times from plan.json's totals, the film's figures from coating.json; a figure
missing from the files, or not a number, shows as "-"."""

from __future__ import annotations

import numpy as np

from sprayplan.view.scene import Scene


def number(value) -> float | None:
    """A figure from plan.json or coating.json as a finite float, or None (absent, or not a number)."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not np.isfinite(value):
        return None
    return float(value)


def _fmt(value, fmt: str = "{:,.0f}", scale: float = 1.0) -> str:
    x = number(value)
    return "-" if x is None else fmt.format(x * scale)


def measured_interval(table: dict) -> str:
    """`` (95 %: lo-hi %)``: the interval of a measuring-point table's share in spec
    (``coating.report.share_interval``), or "" for a table without one (a plan written before it)."""
    ci = table.get("share_in_spec_ci95") if isinstance(table, dict) else None
    if not (isinstance(ci, list) and len(ci) == 2 and all(number(v) is not None for v in ci)):
        return ""
    return f" (95 %: {100 * number(ci[0]):.1f}-{100 * number(ci[1]):.1f} %)"


def open_surface(film: dict) -> str:
    """``, x % over the surface a gun faces square (nothing within d mm in front; recessed a m^2, y % in
    spec), z % over the open surface some robot reaches``: a cell plan's film over its open and recessed surface and
    over the open surface some robot reaches (``cells.film.film_report``), or "" for a film without them (a plan
    written before; the last part is left out for a film without ``open_reached``)."""
    flat, deep = (film.get(k) if isinstance(film, dict) else None for k in ("open", "recessed"))
    if not (isinstance(flat, dict) and isinstance(deep, dict)):
        return ""
    share, depth = number(flat.get("share_in_spec")), number(flat.get("recess_mm"))
    deep_share, deep_area = number(deep.get("share_in_spec")), number(deep.get("area_mm2"))
    if share is None or depth is None:
        return ""
    text = f", {100 * share:.1f} % over the surface a gun faces square (nothing within {depth:g} mm in front"
    if deep_area and deep_share is not None:
        text += f"; recessed {deep_area / 1e6:.3g} m^2, {100 * deep_share:.1f} % in spec"
    text += ")"
    both = film.get("open_reached")
    both_share = number(both.get("share_in_spec")) if isinstance(both, dict) else None
    if both_share is not None:
        text += f", {100 * both_share:.1f} % over the open surface some robot reaches"
    return text


def out_of_spec_causes(film: dict) -> str:
    """``out of spec: unreached a %, recessed b %, bare c %, thin d %, thick e % of the painted area``: a cell
    plan's film out of spec by cause (``cells.film.out_of_spec``), or "" for a film without it."""
    causes = film.get("out_of_spec") if isinstance(film, dict) else None
    names = ("unreached", "recessed", "bare", "thin", "thick")
    if not isinstance(causes, dict) or any(number(causes.get(k)) is None for k in names):
        return ""
    return "out of spec: " + ", ".join(f"{k} {100 * number(causes[k]):.1f} %" for k in names) + " of the painted area"


def summary_rows(scene: Scene) -> list[tuple[str, list[tuple[str, str]]]]:
    """The summary panel's tables: (title, [(label, value)]); a figure missing from the files shows as '-'."""
    t = scene.totals
    plan = scene.plan
    kinds = [s.kind for st in plan.stations for s in st.strokes]
    rows = [
        (
            "plan",
            [
                ("stations", f"{len(plan.stations):,}"),
                ("spray strokes", f"{kinds.count('spray'):,}"),
                ("touch-up strokes", f"{kinds.count('touch-up'):,}"),
                ("transfers", f"{kinds.count('transfer'):,}"),
                ("waypoints", f"{sum(len(st.reachable) for st in plan.stations):,}"),
                ("unreachable waypoints", f"{sum(int((~st.reachable).sum()) for st in plan.stations):,}"),
                ("SQP waypoints", f"{sum(int((st.method == 'sqp').sum()) for st in plan.stations):,}"),
                ("points no station reaches", f"{len(plan.unassigned):,}"),
                ("spray length", _fmt(t.get("spray_length_mm"), "{:,.1f} m", 1e-3)),
                ("transfer length", _fmt(t.get("transfer_length_mm"), "{:,.1f} m", 1e-3)),
                ("gantry travel", _fmt(t.get("platform_travel_mm"), "{:,.1f} m", 1e-3)),
                ("cycle time", _fmt(t.get("cycle_time_s"), "{:,.0f} s")),
                *(
                    [("cycle time, length over speed", _fmt(t["cycle_time_length_over_speed_s"], "{:,.0f} s"))]
                    if "cycle_time_length_over_speed_s" in t
                    else []
                ),
                ("planning time", _fmt(t.get("planning_time_s"), "{:,.1f} s")),
            ],
        )
    ]
    c = t.get("collisions")
    if isinstance(c, dict) and c.get("checked") is False:
        rows.append(("collisions", [("checked", f"no ({c.get('reason', '')})")]))
    elif isinstance(c, dict):
        rows.append(
            (
                "collisions",
                [
                    ("clearance", _fmt(c.get("clearance_mm"), "{:g} mm")),
                    ("waypoints in collision as planned", _fmt(c.get("in_collision_before_repair"), "{:,.0f}")),
                    ("repaired", _fmt(c.get("repaired"), "{:,.0f}")),
                    ("left flagged", _fmt(c.get("flagged_waypoints"), "{:,.0f}")),
                    ("motions flagged", _fmt(c.get("flagged_motions"), "{:,.0f}")),
                ],
            )
        )
    film = scene.film
    p = film.get("painted") if film is not None else None
    if isinstance(p, dict) and number(p.get("count")):
        g = lambda table, key, fmt, scale=1.0: _fmt(table.get(key), fmt, scale)
        film_rows = [
            ("spec", f"{scene.target_um:g} +- {scene.tolerance_um:g} um"),
            ("mean", g(p, "mean_um", "{:.1f} um")),
            ("std / mean", f"{g(p, 'std_um', '{:.2f} um')} / {g(p, 'cv', '{:.3f}')}"),
            ("min .. max", f"{g(p, 'min_um', '{:.1f}')} .. {g(p, 'max_um', '{:.1f} um')}"),
            ("in spec", g(p, "share_in_spec", "{:.1f} % of the painted area", 100.0)),
            ("below / above", f"{g(p, 'share_below', '{:.1f} %', 100.0)} / {g(p, 'share_above', '{:.1f} %', 100.0)}"),
            (
                "painted area",
                f"{g(p, 'area_mm2', '{:.3f} m^2', 1e-6)} ({g(p, 'share_of_area', '{:.1f} %', 100.0)} of the surface)",
            ),
        ]
        m = film.get("measuring_points")
        if isinstance(m, dict) and number(m.get("count")):
            film_rows.append(
                (
                    f"{int(m['count'])} measuring points",
                    f"mean {g(m, 'mean_um', '{:.1f} um')}, {g(m, 'min_um', '{:.1f}')} .. {g(m, 'max_um', '{:.1f}')}, "
                    f"{g(m, 'share_in_spec', '{:.1f} %', 100.0)} in spec{measured_interval(m)}",
                )
            )
        paint = film.get("paint")
        if isinstance(paint, dict) and paint:
            film_rows.append(
                (
                    "paint",
                    f"{g(paint, 'wet_paint_ml', '{:,.0f} mL')} wet, "
                    f"{g(paint, 'share_of_solids_on_part', '{:.0f} %', 100.0)} of the solids on the part",
                )
            )
        rows.append(("film (painted area)", film_rows))
    return rows
