"""The film's colour scale, shared by the HTML viewer (plotly) and the picture report (matplotlib).

A diverging scale centred on the target: greens inside the spec (``target +- tolerance``, darkest at the
target), blues below it (deep blue for bare), reds above it (deep red for twice the tolerance band and more).
The colour jumps at the spec's limits, so the edge of the in-spec area shows on the part as a line.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Colours of the scale (RGB hex): below the spec (deep -> light blue), inside it (light -> dark -> light
#: green), above it (light -> deep red).
BARE, THIN = "#08306b", "#9ecae1"
SPEC_EDGE, SPEC_MID = "#c7e9c0", "#41ab5d"
THICK, HEAVY = "#fcae91", "#99000d"
#: Stations' colours (qualitative, cycled).
STATION_COLOURS = (
    "#1f77b4",
    "#ff7f0e",
    "#9467bd",
    "#8c564b",
    "#e377c2",
    "#17becf",
    "#bcbd22",
    "#7f7f7f",
    "#393b79",
    "#ad494a",
    "#637939",
    "#d6616b",
)
#: The colour of a bare part (no film simulated).
GREY = "#b4b4b4"
#: The robots of a cell, in the cell's order (``areas.png``, ``cell.html``).
ROBOT_COLOURS = ("#d62728", "#1f77b4", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b")


@dataclass(frozen=True)
class FilmScale:
    """The colour scale of a film spec: ``cmin .. cmax`` um, with colour stops at fractions of it.

    Attributes
    ----------
    target_um, tolerance_um : float
    cmin, cmax : float
        The film at the scale's ends (a film outside is drawn in the end colour).
    stops : tuple of (float, str)
        (fraction of ``cmin .. cmax``, colour), non-decreasing; a fraction given twice is a jump.
    """

    target_um: float
    tolerance_um: float
    cmin: float
    cmax: float
    stops: tuple

    @property
    def ticks(self) -> tuple[list[float], list[str]]:
        """Colour-bar ticks: the scale's ends, the spec's limits and the target, with their labels."""
        t, tol = self.target_um, self.tolerance_um
        values = [self.cmin, t - tol, t, t + tol, self.cmax] if tol > 0 else [self.cmin, t, self.cmax]
        labels = [f"<= {self.cmin:g}"] + [f"{v:g}" for v in values[1:-1]] + [f">= {self.cmax:g}"]
        labels[values.index(t)] = f"{t:g} target"
        if tol > 0:
            labels[1], labels[3] = f"{t - tol:g} (-{tol:g})", f"{t + tol:g} (+{tol:g})"
        return values, labels

    def fraction(self, thickness_um) -> np.ndarray:
        """Where a film falls on the scale, clipped to 0..1."""
        return np.clip((np.asarray(thickness_um, float) - self.cmin) / (self.cmax - self.cmin), 0.0, 1.0)

    def rgb(self, thickness_um) -> np.ndarray:
        """(n, 3) float in 0..1: the colour of each film value (the same as plotly's and matplotlib's)."""
        f = self.fraction(thickness_um)
        at = np.array([s[0] for s in self.stops])
        colours = np.array([hex_rgb(s[1]) for s in self.stops])
        out = np.empty((len(f), 3))
        # right-continuous at a jump: a value exactly at a spec limit is inside the spec
        i = np.clip(np.searchsorted(at, f, side="right") - 1, 0, len(at) - 2)
        span = at[i + 1] - at[i]
        w = np.divide(f - at[i], span, out=np.zeros_like(f), where=span > 0)
        for k in range(3):
            out[:, k] = colours[i, k] + w * (colours[i + 1, k] - colours[i, k])
        return out

    def plotly(self) -> list:
        """The scale as a plotly ``colorscale``."""
        return [[float(f), c] for f, c in self.stops]

    def matplotlib(self):
        """The scale as a matplotlib colormap (to use with ``Normalize(cmin, cmax)``)."""
        from matplotlib.colors import LinearSegmentedColormap

        return LinearSegmentedColormap.from_list("sprayplan_film", [(f, c) for f, c in self.stops], N=1024)


def hex_rgb(colour: str) -> tuple[float, float, float]:
    """'#rrggbb' as three floats in 0..1."""
    return tuple(int(colour[k : k + 2], 16) / 255.0 for k in (1, 3, 5))


def film_scale(target_um: float, tolerance_um: float) -> FilmScale:
    """The scale for ``target_um +- tolerance_um``: from ``target - span`` (at least 0) to ``target + span``
    with ``span`` four tolerances (at least a fifth of the target), so that the spec band takes a quarter of
    the scale and a film off by several tolerances is still told apart."""
    span = max(4.0 * tolerance_um, 0.2 * target_um)
    cmin, cmax = max(0.0, target_um - span), target_um + span
    width = cmax - cmin
    lo = max((target_um - tolerance_um - cmin) / width, 0.0)
    mid = (target_um - cmin) / width
    hi = (target_um + tolerance_um - cmin) / width
    if tolerance_um > 0:
        stops = (
            (0.0, BARE),
            (lo, THIN),
            (lo, SPEC_EDGE),
            (mid, SPEC_MID),
            (hi, SPEC_EDGE),
            (hi, THICK),
            (1.0, HEAVY),
        )
    else:
        stops = ((0.0, BARE), (mid, SPEC_MID), (1.0, HEAVY))
    return FilmScale(float(target_um), float(tolerance_um), float(cmin), float(cmax), stops)
