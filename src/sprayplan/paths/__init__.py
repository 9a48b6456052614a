"""Spray paths: slicing a part into section polylines, processing them, and turning them into strokes."""
