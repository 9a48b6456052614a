"""Gantry stations (seed 000, section 5.1): where the gantry stops, and what is painted from each stop."""

from sprayplan.stations.partition import (
    CoverModel,
    EnvelopeRectangle,
    StationAssignment,
    assign_greedy,
    circle_cover,
    envelope_rectangle,
    principal_angle,
)

__all__ = [
    "CoverModel",
    "EnvelopeRectangle",
    "StationAssignment",
    "assign_greedy",
    "circle_cover",
    "envelope_rectangle",
    "principal_angle",
]
