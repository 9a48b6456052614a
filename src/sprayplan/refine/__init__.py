"""Refinement of a planned program against its predicted film: the speed at every waypoint tuned to the film
(``tuning``), touch-up strokes aimed at what is still under-painted (``touchup``), run from the planned
stations or from gantry stations added for them (``extend``, ``added_stations``); ``stage`` runs them as one
stage of the main job.
"""
