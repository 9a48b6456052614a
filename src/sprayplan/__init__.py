"""sprayplan: from a part's geometry to a spray-painting robot program."""

from __future__ import annotations

__version__ = "0.1.0"
