"""Where a headless Chromium is, and the flags it runs with here (for the viewer's browser test and its
benchmark): a closed network and no GPU (WebGL through SwiftShader, on the CPU)."""

from __future__ import annotations

import os
import shutil

#: How to get a Chromium when none is found.
HOW_TO_GET = "install Debian's chromium (apt-get install chromium) or set SPRAYPLAN_CHROMIUM to a Chromium binary"

#: Chromium's flags: no sandbox (root in a container), SwiftShader WebGL, and no background connections (which a
#: closed network refuses, many at a time).
FLAGS = (
    "--no-sandbox",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
)


def find_chromium() -> str | None:
    """``$SPRAYPLAN_CHROMIUM``, else ``chromium`` or ``chromium-browser`` on the PATH, else None."""
    return os.environ.get("SPRAYPLAN_CHROMIUM") or shutil.which("chromium") or shutil.which("chromium-browser")
