"""The report's faster drawing (``view.report``) draws what it drew before:

- the part's backdrop, resampled to each picture's pixels when drawn (``_BackdropImage``), shows what
  ``imshow(backdrop.image, interpolation="bilinear")`` showed, the right way up, shrunk and enlarged, and the
  axes' limits stop at its edges as they did at the image's;
- ``_save`` writes the pixels ``savefig`` wrote, without the alpha channel of an opaque picture.

Small synthetic parts: no plan needed (``tests/test_speed_outputs.py`` checks a planned part's pictures).
"""

from __future__ import annotations

import numpy as np
import pytest

from sprayplan.view import report
from sprayplan.view.scene import Surface


def _l_shaped_part() -> Surface:
    """An L of two rectangles (four triangles), 1000 x 600 mm, its foot at the bottom right: no symmetry."""
    v = np.array(
        [
            [0, 0, 0],
            [1000, 0, 0],
            [1000, 200, 0],
            [0, 200, 0],
            [0, 600, 0],
            [250, 600, 0],
            [250, 200, 0],
        ],
        dtype=float,
    )
    faces = np.array([[0, 1, 2], [0, 2, 3], [3, 6, 5], [3, 5, 4]])
    normals = np.tile([0.0, 0.0, 1.0], (len(v), 1))
    return Surface(v, faces, normals, np.full(len(v), 1.0))


def _pixels(canvas) -> np.ndarray:
    return np.asarray(canvas.buffer_rgba())[..., :3].astype(int)


def _drawn(backdrop, with_imshow: bool, reach: np.ndarray):
    """A station-like axes showing the backdrop (by the artist, or by imshow as before) and a point ``reach``
    that widens the data limits on one side; returns the pixels inside the axes and the axes' limits."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = report._figure(report.ReportSettings())
    report._finish(fig)
    ax = fig.add_subplot()
    canvas = FigureCanvasAgg(fig)
    if with_imshow:
        ax.imshow(backdrop.image, extent=backdrop.extent, origin="upper", interpolation="bilinear", zorder=0)
        x0, x1, y0, y1 = backdrop.extent
        ax.update_datalim(np.array([[x0, y0], [x1, y1]]))
    else:
        backdrop.draw(ax)
    ax.update_datalim(reach[None, :])
    ax.set_aspect("equal")
    ax.autoscale_view()
    canvas.draw()
    box = ax.bbox  # the canvas' rows from the top, inside the spines
    rows = slice(int(fig.bbox.height - box.y1) + 2, int(fig.bbox.height - box.y0) - 2)
    return _pixels(canvas)[rows, int(box.x0) + 2 : int(box.x1) - 2], (ax.get_xlim(), ax.get_ylim())


@pytest.mark.parametrize("width_px", [1600, 120])  # shrunk into the axes, and enlarged
def test_the_backdrop_artist_draws_what_imshow_drew(width_px):
    backdrop = report._Backdrop(_l_shaped_part(), width_px=width_px)
    for reach in (np.array([1600.0, 300.0]), np.array([500.0, -700.0])):
        new, new_limits = _drawn(backdrop, False, reach)
        old, old_limits = _drawn(backdrop, True, reach)
        assert np.allclose(new_limits, old_limits, rtol=0, atol=1e-9)  # margins stop at the part's edges
        # the same pixels, within a level (imshow's float image to bytes): the same resampling, the same place
        assert np.abs(new - old).max() <= 1, (width_px, reach)
        # the right way up: the L's upright on the left, its foot along the bottom, nothing at the top right
        grey = (new < 250).all(axis=2) & (new > 200).all(axis=2)
        rows, cols = np.nonzero(grey.sum(axis=1) > 20)[0], np.nonzero(grey.sum(axis=0) > 20)[0]
        part = grey[rows.min() : rows.max() + 1, cols.min() : cols.max() + 1]
        h, w = part.shape
        assert h > 100 and w > 100
        assert part[: h // 2, w // 2 :].mean() < 0.01
        assert part[: h // 2, : w // 5].mean() > 0.95 and part[-h // 5 :, :].mean() > 0.95


def test_no_backdrop_without_a_part():
    from matplotlib.figure import Figure

    backdrop = report._Backdrop(None)
    assert backdrop.image is None
    ax = Figure().add_subplot()
    before = len(ax.get_children())
    backdrop.draw(ax)
    assert len(ax.get_children()) == before


def test_save_writes_what_savefig_wrote(tmp_path):
    from PIL import Image

    fig = report._figure(report.ReportSettings())
    report._finish(fig)
    ax = fig.add_subplot()
    ax.plot([0, 1, 2], [0, 1, 0.5], "o-", color="#3182bd")
    ax.set_title("a title", fontsize=11)
    report._save(fig, tmp_path / "new.png")
    fig.savefig(tmp_path / "old.png", format="png", dpi=fig.dpi)
    new, old = Image.open(tmp_path / "new.png"), Image.open(tmp_path / "old.png")
    assert new.mode == "RGB" and new.size == old.size == report.ReportSettings().size_px
    assert np.array_equal(np.asarray(new), np.asarray(old.convert("RGB")))
    assert new.info["Software"] == old.info["Software"]
    # a picture that is not opaque throughout keeps its alpha channel
    fig.patch.set_alpha(0.0)
    ax.patch.set_alpha(0.0)
    report._save(fig, tmp_path / "clear.png")
    assert Image.open(tmp_path / "clear.png").mode == "RGBA"
