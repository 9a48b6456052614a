"""The ``sprayplan`` command line: ``main(argv=None)`` (``cli.main``), one module per group of subcommands.

``common`` holds the shared option parsers and the progress display, ``plan`` the main job's ``plan`` and
``simulate``, ``robots`` the ``fk`` and ``ik`` commands.
"""

from sprayplan.cli.main import main

__all__ = ["main"]
