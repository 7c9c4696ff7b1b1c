"""csgnb.display: the backend follows PYVISTA_JUPYTER_BACKEND, static views are PNGs, html views are offline."""

import html
import re
import threading

import numpy as np
import pytest
import pyvista as pv
from IPython.display import HTML, Image

from csgnb import display


def _scene(shape=(1, 1), text=None):
    plotter = pv.Plotter(off_screen=True, shape=shape, window_size=(320, 240), border=False)
    for k in range(shape[1]):
        plotter.subplot(0, k)
        plotter.add_mesh(pv.Cube(), color="tan")
        if text:
            plotter.add_text(f"{text} {k}", font_size=10, color="black")
    return plotter


def test_backend_follows_the_environment(monkeypatch):
    monkeypatch.setenv("PYVISTA_JUPYTER_BACKEND", "static")
    assert display.jupyter_backend() == "static"
    monkeypatch.setenv("PYVISTA_JUPYTER_BACKEND", "HTML")
    assert display.jupyter_backend() == "html"
    monkeypatch.delenv("PYVISTA_JUPYTER_BACKEND")
    assert display.jupyter_backend() == "html"
    assert display.jupyter_backend("none") == "none"


def test_unknown_backend_is_refused_with_the_choices(monkeypatch):
    monkeypatch.setenv("PYVISTA_JUPYTER_BACKEND", "webgl")
    with pytest.raises(ValueError, match="PYVISTA_JUPYTER_BACKEND='webgl'.*static"):
        display.jupyter_backend()
    with pytest.raises(ValueError, match="backend='x'"):
        display.show(_scene(), backend="x")


def test_static_is_a_png_of_the_window_and_writes_the_file(tmp_path):
    plotter = _scene()
    out = display.show(plotter, tmp_path / "cube.png", backend="static")
    assert isinstance(out, Image) and out.data[:8] == b"\x89PNG\r\n\x1a\n"
    assert (tmp_path / "cube.png").read_bytes()[:4] == b"\x89PNG"
    assert plotter.render_window is None  # closed
    with pytest.raises(ValueError, match="closed"):
        display.show(plotter, backend="static")


def test_html_is_a_self_contained_vtkjs_scene_with_the_texts_laid_over(tmp_path):
    out = display.show(_scene(shape=(1, 2), text="panel"), tmp_path / "two.png", backend="html")
    assert isinstance(out, HTML)
    assert 'class="csgnb-scene"' in out.data and (tmp_path / "two.png").exists()
    page = html.unescape(re.search(r'srcdoc="([^"]*)"', out.data).group(1))
    assert "OfflineLocalView" in page and "base64Str" in page  # the vtk.js viewer and the scene data, inline
    assert not re.search(r'<script[^>]+src="https?:', page) and not re.search(r'<link[^>]+href="https?:', page)
    # One caption per subplot, in its half of the view.
    assert "panel 0" in out.data and "panel 1" in out.data
    assert "left:0.000%" in out.data and "left:50.000%" in out.data
    # The view fits a narrower output area: at most the window's width, its aspect kept.
    assert "width:100%;max-width:320px;aspect-ratio:320/240" in out.data


def test_show_works_outside_the_main_thread_as_in_a_widget_callback():
    result = {}

    def callback():
        result["out"] = display.show(_scene(), backend="static")

    worker = threading.Thread(target=callback)
    worker.start()
    worker.join()
    assert isinstance(result["out"], Image)


def test_none_shows_nothing_but_still_writes_the_picture(tmp_path):
    assert display.show(_scene(), tmp_path / "n.png", backend="none") is None
    assert (tmp_path / "n.png").exists()


def test_snapshot_and_aim():
    plotter = _scene()
    display.aim(plotter, (0, 0, 0), 5.0, direction=(0, 0, 2), up=(0, 1, 0))
    assert np.allclose(plotter.camera.position, (0, 0, 5)) and np.allclose(plotter.camera.focal_point, 0)
    image = display.snapshot(plotter)
    assert image.shape == (240, 320, 3) and image.dtype == np.uint8 and image.std() > 0
    with pytest.raises(ValueError, match="non-zero"):
        display.aim(_scene(), (0, 0, 0), 1.0, direction=(0, 0, 0))


def test_legend_shows_in_both_backends(tmp_path):
    plotter = _scene()
    display.add_legend(plotter, [("inside", "#3b6fb6"), ("outside", "white")])
    out = display.show(plotter, tmp_path / "legend.png", backend="html")
    assert "inside" in out.data and "background:rgb(59,111,182)" in out.data
    plotter = _scene()
    with pytest.raises(ValueError, match="corner"):
        display.add_legend(plotter, [("a", "red")], corner="middle")


def _foreground_box(image: np.ndarray) -> tuple[int, int, int, int]:
    """Rows and columns ``(top, bottom, left, right)`` spanned by pixels that differ from the corner pixel."""
    rows, cols = np.nonzero(np.any(image != image[0, 0], axis=2))
    return rows.min(), rows.max(), cols.min(), cols.max()


@pytest.mark.parametrize("shape, size, direction", [
    ("long box", (400, 300), (1.0, -2.0, 0.9)),
    ("tall drill", (640, 480), (1.0, -1.0, 0.3)),
    ("flat plate", (480, 640), (0.2, -1.0, 2.0)),
    ("off-centre cube", (300, 300), (-1.0, 0.5, 0.4)),
    ("octahedron", (640, 480), (43.0, 21.0, 35.0)),  # fitted to its points, not to its (much larger) bounding box
])
def test_aim_fits_the_scene_in_the_picture_centred(shape, size, direction):
    """Fitted: nothing touches the frame, the scene fills the picture on its tightest side, centred (the old fixed
    cameras cut chapter 05's drill off at the top and the tour's octree cube at the bottom)."""
    import pyvista as pv

    solid = {"long box": pv.Box((-10, 30, -2, 2, -1, 1)),
             "tall drill": pv.Cylinder(radius=1, height=12, direction=(0, 0, 1)),
             "flat plate": pv.Box((-50, 50, -30, 30, 0, 3)),
             "off-centre cube": pv.Cube(center=(100, -40, 7), x_length=2.0),
             "octahedron": pv.PlatonicSolid("octahedron", radius=9.0)}[shape]
    plotter = pv.Plotter(off_screen=True, window_size=size)
    plotter.add_mesh(solid, color="orange")
    display.aim(plotter, direction=direction)
    top, bottom, left, right = _foreground_box(display.snapshot(plotter))
    w, h = size
    gaps = np.array([top, h - 1 - bottom, left, w - 1 - right])
    assert gaps.min() >= 1, f"{shape} touches the frame: gaps {gaps}"
    assert min(gaps[0] + gaps[1], gaps[2] + gaps[3]) <= 0.2 * min(w, h), f"{shape} does not fill the picture: {gaps}"
    assert abs(gaps[0] - gaps[1]) <= 0.08 * h and abs(gaps[2] - gaps[3]) <= 0.08 * w, f"{shape} off centre: {gaps}"


def test_aim_refuses_what_it_cannot_fit():
    with pytest.raises(ValueError, match="parallel"):
        display.aim(_scene(), direction=(0, 0, 1), up=(0, 0, 2))
    with pytest.raises(ValueError, match="finite bounds"):
        display.aim(_scene(), bounds=(0, 1, 0, 1, 1, 0))
