"""Collision checks of a plan against the part, the floor and the cell (issue 16, part 1).

:mod:`~sprayplan.collision.bodies` the bodies as data, :mod:`~sprayplan.collision.settings` the settings,
:mod:`~sprayplan.collision.cell` the model built once per plan (``CellCollision``),
:mod:`~sprayplan.collision.motion` the step bound between waypoints, :mod:`~sprayplan.collision.heights` the
stations' heights chosen with the model.
"""
