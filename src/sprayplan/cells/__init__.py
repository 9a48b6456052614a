"""Paint cells as data (:mod:`sprayplan.cells.spec`; schema in docs/cells.md) and their presets."""

from sprayplan.cells.spec import Cell, CellRobot, PlacedPart, Track, cell_from_dict, list_cells, load_cell, place_part

__all__ = ["Cell", "CellRobot", "PlacedPart", "Track", "cell_from_dict", "list_cells", "load_cell", "place_part"]
