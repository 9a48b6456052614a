"""Pictures of a plan: the self-contained HTML viewer (``html``) and the PNG picture report (``report``), both
drawn from a :class:`~sprayplan.view.scene.Scene` gathered from a finished job or a plan folder."""

from sprayplan.view.scene import Scene, Surface, scene_from_folder, scene_from_result

__all__ = ["Scene", "Surface", "scene_from_folder", "scene_from_result"]
