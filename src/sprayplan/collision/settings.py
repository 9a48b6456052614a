"""Settings of the collision checks: :class:`~sprayplan.config.CollisionConfig` (``[collision]``), kept in
``sprayplan.config`` with the job's other sections and named here too."""

from sprayplan.config import CollisionConfig

__all__ = ["CollisionConfig"]
