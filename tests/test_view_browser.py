"""plan.html in a real browser: Debian's headless Chromium, driven by playwright (never ``playwright install``:
the browser is the system's). Skipped, saying how to get it, when no Chromium is installed."""

from __future__ import annotations

import numpy as np
import pytest

from sprayplan.view.browser import FLAGS, HOW_TO_GET, find_chromium
from sprayplan.view.html import PLOT_ID, read_viewer_figure

CHROMIUM = find_chromium()

pytestmark = pytest.mark.skipif(CHROMIUM is None, reason=f"no Chromium for the browser test: {HOW_TO_GET}")


@pytest.fixture(scope="module")
def browser():
    playwright = pytest.importorskip("playwright.sync_api", reason="playwright (the test extra) is not installed")
    with playwright.sync_playwright() as p:
        chromium = p.chromium.launch(executable_path=CHROMIUM, args=list(FLAGS))
        yield chromium
        chromium.close()


def _open(browser, path):
    page = browser.new_page(viewport={"width": 1400, "height": 1000})
    errors = []
    page.on("pageerror", lambda e: errors.append(f"page error: {e}"))
    page.on("console", lambda m: errors.append(f"console {m.type}: {m.text}") if m.type == "error" else None)
    page.on("request", lambda r: None if r.url.startswith(("file:", "data:", "blob:")) else errors.append(r.url))
    page.goto(path.as_uri())
    page.wait_for_function(
        f"() => {{ const d = document.getElementById('{PLOT_ID}');"
        " return d && d._fullLayout && d.data && d.data.length && d.querySelector('canvas'); }",
        timeout=120_000,
    )
    page.wait_for_timeout(1_000)  # WebGL draws after the plot exists
    return page, errors


def test_plan_html_opens_in_chromium_and_shows_the_film(browser, planned_with_film, tmp_path):
    path = planned_with_film / "plan.html"
    page, errors = _open(browser, path)
    names = page.evaluate(f"() => document.getElementById('{PLOT_ID}').data.map(t => t.name)")
    expected, _ = read_viewer_figure(path.read_text(encoding="utf-8"))
    assert names == [t["name"] for t in expected]
    assert names[0] == "part: dry film (um)"
    # everything but the part switched off: the screenshot is the film's colours on the part
    page.evaluate(
        f"() => {{ const d = document.getElementById('{PLOT_ID}');"
        " Plotly.restyle(d, {visible: false}, d.data.map((_, i) => i).slice(1)); }"
    )
    page.wait_for_timeout(1_000)
    shot = tmp_path / "part.png"
    page.screenshot(path=str(shot))
    from matplotlib.image import imread

    pixels = imread(shot)[:, :, :3].reshape(-1, 3)
    assert len(np.unique((pixels * 255).round(), axis=0)) > 100  # not blank
    r, g, b = pixels.T
    green = (g > r + 0.08) & (g > b + 0.03)  # the in-spec greens, shaded by the lights
    assert green.mean() > 0.02, f"only {100 * green.mean():.2f} % green pixels"
    assert errors == []
    page.close()


def test_a_legend_click_switches_a_trace_and_a_button_a_layer(browser, planned_with_film):
    page, errors = _open(browser, planned_with_film / "plan.html")
    names = page.evaluate(f"() => document.getElementById('{PLOT_ID}').data.map(t => t.name)")
    index = names.index("transfers (gun off)")
    page.locator("g.legend g.traces", has_text="transfers (gun off)").locator("rect.legendtoggle").click()
    page.wait_for_timeout(1_000)  # plotly waits for a second click (a double click) first
    visible = page.evaluate(f"() => document.getElementById('{PLOT_ID}').data[{index}].visible")
    assert visible == "legendonly"
    # a layer button switches every trace of its layer: here all the stations' strokes, off and on again
    strokes = [i for i, n in enumerate(names) if n.startswith("stop ")]
    for expected in ("legendonly", True):
        page.locator("g.updatemenu-button", has_text="strokes").click()
        page.wait_for_timeout(1_000)
        shown = page.evaluate(f"() => document.getElementById('{PLOT_ID}').data.map(t => t.visible)")
        assert [shown[i] for i in strokes] == [expected] * len(strokes)
        assert shown[0] is None  # the part stays
    assert errors == []
    page.close()
