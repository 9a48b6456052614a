"""Pictures of a cell plan a person can check (``sprayplan plan --cell``): ``areas.png``, the surface coloured
by the robot that paints it, ``film.png``, the film over the whole body, and ``film_timed.png``, the film the
robots leave at the speeds they make within their limits, each from two opposite
three-quarter views so that both sides of a body show. Faces no robot reaches are grey in ``areas.png``; the
film's colours are ``export.film.thickness_colours`` (blue bare, green in spec, red twice the target).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from sprayplan.view.colours import ROBOT_COLOURS

#: The two views (elevation, azimuth), degrees.
VIEWS = ((30.0, -60.0), (30.0, 120.0))
UNREACHED = "#b0b0b0"


def _figure():
    from matplotlib.figure import Figure

    return Figure(figsize=(16, 6.5), dpi=90)


def _axes(fig, part, k: int):
    ax = fig.add_subplot(1, 2, k + 1, projection="3d")
    lo, hi = part.bounds
    ext = np.maximum(hi - lo, 1e-9)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect(tuple(ext / ext.max()), zoom=1.25)
    ax.view_init(*VIEWS[k])
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_zlabel("z (mm)")
    ax.tick_params(labelsize=7)
    return ax


def _save(fig, path: str) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from sprayplan.export.files import atomic_output

    FigureCanvasAgg(fig)
    with atomic_output(path, "wb") as handle:
        fig.savefig(handle, format="png", dpi=fig.dpi)


def _surface(ax, part, colours) -> None:
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    ax.add_collection3d(Poly3DCollection(part.triangles, facecolors=colours, edgecolor="none"))


def areas_picture(path: str, plan) -> None:
    """``areas.png``: each face in its robot's colour, with a legend of the robots and their surface."""
    from matplotlib.patches import Patch

    from sprayplan.view.colours import hex_rgb

    fr = plan.assignment.face_robot
    palette = np.array([hex_rgb(ROBOT_COLOURS[i % len(ROBOT_COLOURS)]) for i in range(len(plan.cell.robots))])
    colours = np.where((fr >= 0)[:, None], palette[np.maximum(fr, 0)], hex_rgb(UNREACHED))
    fig = _figure()
    for k in range(2):
        _surface(_axes(fig, plan.part, k), plan.part, colours)
    handles = [
        Patch(color=ROBOT_COLOURS[i % len(ROBOT_COLOURS)], label=f"{r.name} ({a / 1e6:.2f} m^2)")
        for i, (r, a) in enumerate(zip(plan.cell.robots, plan.assignment.robot_area_mm2))
    ]
    handles.append(Patch(color=UNREACHED, label=f"unreached ({plan.assignment.unreached_mm2 / 1e6:.3f} m^2)"))
    fig.legend(handles=handles, loc="lower center", ncol=len(handles))
    fig.suptitle(f"{plan.part.name} in cell {plan.cell.name}: {len(plan.areas)} areas, the robot of each face")
    _save(fig, path)


def film_picture(path: str, plan, target_um: float, tolerance_um: float, timed: bool = False) -> None:
    """``film.png``: each face coloured by the mean film of the samples nearest it; with ``timed``,
    ``film_timed.png``: the film the robots leave at their timed speeds (``plan.timed_film``)."""
    from sprayplan.export.film import thickness_colours

    film = plan.timed_film if timed else plan.film
    centres = plan.part.triangles.mean(axis=1)
    nearest = cKDTree(centres).query(film.points)[1]
    m = len(centres)
    weight = np.bincount(nearest, film.area_mm2, m)
    mean = np.divide(
        np.bincount(nearest, film.area_mm2 * film.thickness_um, m), weight, out=np.zeros(m), where=weight > 0
    )
    colours = thickness_colours(mean, target_um, tolerance_um) / 255.0
    fig = _figure()
    for k in range(2):
        _surface(_axes(fig, plan.part, k), plan.part, colours)
    report = plan.report.get("film", {})
    whole = (report.get("at_timed_speeds", {}) if timed else report).get("whole", {})
    share = whole.get("share_in_spec")
    note = f": {100 * share:.1f} % within {target_um:g} +- {tolerance_um:g} um" if share is not None else ""
    what = "at the robots' timed speeds " if timed else ""
    fig.suptitle(f"film {what}over {plan.part.name} (blue bare, green in spec, red twice the target){note}")
    _save(fig, path)
