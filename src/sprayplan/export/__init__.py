"""Every file the main job writes, and the readers of sprayplan's own formats that round-trip them.

``files`` (atomic writes, the JSON header check), ``plan_json`` (plan.json and waypoints.csv), ``plan_read``
(plan.json read back), ``paths_json`` (paths.json), ``film`` (coating.json, thickness.ply, thickness.csv).
"""
