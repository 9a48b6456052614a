"""Benchmark of the pictures of a plan (issue 14): the time to write plan.html and report/, their sizes, and
the time a headless Chromium takes to open plan.html until plotly has drawn it.

Parts: the demo roof (z > 1000, 50 um target: what ``sprayplan demo`` plans), the reach part (x > -250,
50 um target) and the DTC hull (116k triangles, 6.3 m; planned with ``--simulate``: its film at the plan's
speeds). Each is planned once with ``--no-viewer --no-report``; then, ``--repeat`` times each (median
reported): the scene read from the folder (``view.scene.scene_from_folder``), plan.html written
(``view.html.write_viewer``), report/ drawn (``view.report.write_report_files``), and plan.html opened in
Debian's chromium through playwright (from ``goto`` until the plot's canvas exists and two animation frames
have passed), alternately with a page of plotly.js alone (a one-point 3D figure), which is what any plotly
3D page costs in that browser on that machine at that moment (WebGL here is SwiftShader, on the CPU).
``--keep DIR`` keeps the planned folders, and a second run into the same DIR reuses them.

Usage::

    python bench/bench_view.py [--repeat 3] [--parts demo,reach,hull] [--keep DIR]
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

try:
    import sprayplan  # noqa: F401
except ImportError:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from _data import meshes_dir

from sprayplan.view.browser import FLAGS, find_chromium

CHROMIUM = find_chromium()


def parts() -> dict:
    meshes = meshes_dir()
    return {
        "demo": ("demo roof (z > 1000, 50 um target)", None, ["--thickness-um", "50", "--samples", "420"]),
        "reach": (
            "reach part (x > -250, 50 um target)",
            meshes / "reach_curved_part.ply",
            ["--units", "m", "--region", "x > -250", "--thickness-um", "50"],
        ),
        "hull": (
            "DTC hull (116k triangles, --simulate)",
            meshes / "dtc_ship_hull_ascii.stl.gz",
            ["--units", "m", "--simulate", "--samples", "420"],
        ),
    }


def plan_folder(key: str, root: Path) -> tuple[Path, float]:
    from sprayplan.cli import main

    label, part, options = parts()[key]
    out = root / key
    if (out / "plan.json").exists():  # planned by an earlier run into the same --keep folder
        return out, float("nan")
    start = time.perf_counter()
    if part is None:  # the demo's part and region
        from sprayplan.demo import DEMO_REGION, car_roof
        from sprayplan.export.stl import write_stl_binary

        part = root / "roof.stl"
        part.write_bytes(write_stl_binary(car_roof().triangles, b"demo roof"))
        options = ["--region", DEMO_REGION, *options]
    code = main(["-q", "plan", str(part), *options, "--no-viewer", "--no-report", "-o", str(out)])
    if code != 0:
        raise SystemExit(f"planning {label} failed")
    return out, time.perf_counter() - start


def folder_size(path: Path) -> int:
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())


def baseline_page(root: Path) -> Path:
    """plotly.js alone: a one-point 3D figure written the same way (what any plotly 3D page costs)."""
    import plotly.graph_objects as go

    path = root / "plotly_alone.html"
    go.Figure(go.Scatter3d(x=[0.0], y=[0.0], z=[0.0])).write_html(path, include_plotlyjs=True, div_id="sprayplan-plan")
    return path


def browser_times(page_path: Path, repeat: int, baseline: Path) -> tuple[list[float], list[float]] | None:
    """Seconds until the plot is ready, for the page and for plotly.js alone, alternately in one browser."""
    if CHROMIUM is None:
        print("(no chromium: the browser's load time is not measured; apt-get install chromium)")
        return None
    from playwright.sync_api import sync_playwright

    ready, alone = [], []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=list(FLAGS))
        for _ in range(repeat):
            for path, times in ((page_path, ready), (baseline, alone)):
                page = browser.new_page(viewport={"width": 1400, "height": 1000})
                start = time.perf_counter()
                page.goto(path.as_uri())
                page.wait_for_function(
                    "() => { const d = document.getElementById('sprayplan-plan');"
                    " return d && d._fullLayout && d.querySelector('canvas'); }",
                    timeout=300_000,
                )
                page.evaluate("() => new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
                times.append(time.perf_counter() - start)
                page.close()
        browser.close()
    return ready, alone


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--parts", default="demo,reach,hull")
    parser.add_argument("--keep", help="plan into this folder and keep it (default: a temporary folder)")
    args = parser.parse_args()
    from sprayplan.view.html import write_viewer
    from sprayplan.view.report import write_report_files
    from sprayplan.view.scene import scene_from_folder

    root = Path(args.keep or tempfile.mkdtemp(prefix="bench_view_"))
    root.mkdir(parents=True, exist_ok=True)
    rows = []
    for key in args.parts.split(","):
        label = parts()[key][0]
        folder, planned = plan_folder(key, root)
        scene_s, viewer_s, report_s = [], [], []
        for _ in range(args.repeat):
            t = time.perf_counter()
            scene = scene_from_folder(folder)
            scene_s.append(time.perf_counter() - t)
            t = time.perf_counter()
            drawn = write_viewer(folder / "plan.html", scene)
            viewer_s.append(time.perf_counter() - t)
            report = folder / "report"
            shutil.rmtree(report, ignore_errors=True)
            report.mkdir()
            t = time.perf_counter()
            write_report_files(str(report), scene)
            report_s.append(time.perf_counter() - t)
        html_mb = (folder / "plan.html").stat().st_size / 1e6
        report_mb = folder_size(folder / "report") / 1e6
        images = len(list((folder / "report").glob("*.png")))
        browser = browser_times(folder / "plan.html", args.repeat, baseline_page(root))
        med = statistics.median
        rows.append(
            (
                label,
                f"{planned:.0f}",
                f"{drawn.get('faces', 0):,} -> {drawn.get('drawn_faces', 0):,}",
                f"{drawn['waypoints']:,} -> {drawn['drawn_waypoints']:,}",
                f"{med(scene_s):.2f}",
                f"{med(viewer_s):.2f}",
                f"{html_mb:.1f}",
                f"{med(report_s):.1f}",
                f"{images} / {report_mb:.1f}",
                "-" if browser is None else f"{med(browser[0]):.1f} / {med(browser[1]):.1f}",
            )
        )
        print(f"{label}: done", flush=True)
    print()
    print(
        "| part | planned (s, once) | triangles drawn | waypoints drawn | scene read (s) | plan.html (s) "
        "| plan.html (MB) | report/ (s) | images / MB | browser: plan.html drawn / plotly.js alone (s) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for row in rows:
        print("| " + " | ".join(row) + " |")
    print(f"\nmedians of {args.repeat} runs; folders in {root}")


if __name__ == "__main__":
    main()
