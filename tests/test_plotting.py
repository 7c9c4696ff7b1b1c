"""csgnb.plotting: the on-screen size of every text a notebook shows, and the report each chapter ends with."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import pytest  # noqa: E402

from csgnb import display, plotting  # noqa: E402


@pytest.fixture(autouse=True)
def _fresh_record():
    yield
    plotting._shown.clear()
    plotting._collisions.clear()
    plotting._recording = False
    plt.close("all")
    matplotlib.rcdefaults()


def _figure(width_in: float, title_pt: float, *, axis: bool = True):
    fig, ax = plt.subplots(figsize=(width_in, 3), dpi=100, layout="constrained")
    ax.plot([0, 1], [0, 1])
    ax.set_title("the title", fontsize=title_pt)
    if not axis:
        ax.axis("off")
    return fig


def test_a_wide_figure_shrinks_its_text():
    narrow = dict(plotting.text_sizes(_figure(7, 10)))
    wide = dict(plotting.text_sizes(_figure(17, 10)))
    assert narrow["the title"] == pytest.approx(10 * 100 / 72)  # shown at full size
    # shrunk to 848 px: the title of a 17-inch figure is about 6 px, as the issue measured on screen
    assert 5.5 < wide["the title"] < 7.5
    assert wide["the title"] == pytest.approx(narrow["the title"] * 848 / (17 * 100), rel=0.06)


def test_only_drawn_texts_count():
    sizes = plotting.text_sizes(_figure(6, 12, axis=False))
    assert [text for text, _ in sizes] == ["the title"], "a hidden axis' tick labels are not on screen"


def test_style_makes_every_text_legible_up_to_the_reader_width():
    plotting.use_style(record=False)
    fig, ax = plt.subplots(figsize=(8.4, 3.5))
    ax.plot([1, 2, 3], label="a line")
    ax.set(xlabel="x", ylabel="y", title="a title")
    ax.legend()
    fig.suptitle("a figure title")
    sizes = plotting.text_sizes(fig)
    assert len(sizes) > 8 and min(px for _, px in sizes) >= plotting.MIN_TEXT_PX


def test_report_names_the_small_texts_of_shown_figures_and_scenes():
    import io
    import os

    from IPython.core.pylabtools import print_figure

    plotting.use_style()
    print_figure(_figure(6, 12), "png")  # as Jupyter's inline backend shows a figure
    _figure(3, 5).savefig(os.devnull, format="png")  # saved to a file: not shown
    assert plotting.legibility_report().startswith("1 figures shown, every text at least 11 px")
    _figure(17, 9).savefig(io.BytesIO(), format="png")  # the bytes of a picture for a widget

    import pyvista as pv

    plotter = pv.Plotter(off_screen=True, window_size=(1700, 300))
    plotter.add_mesh(pv.Sphere())
    plotter.add_text("a long caption in the corner of a wide scene", position="upper_left", font_size=5)
    display.show(plotter, backend="none")
    report = plotting.legibility_report()
    lines = report.splitlines()
    assert lines[0].startswith("2 of 3 figures have text under 11 px"), report
    assert lines[0].endswith("0 pairs of texts overlap:"), report
    assert lines[1] == "  figure 2: 13 of 13 texts, the smallest 'the title' 6.3 px", report
    assert lines[2].startswith("  figure 3: 1 of 1 texts, the smallest 'a long caption in the corner"), report
    assert len(lines) == 3


def test_nothing_is_recorded_before_use_style():
    import pyvista as pv

    plotter = pv.Plotter(off_screen=True, window_size=(300, 200))
    plotter.add_text("tiny", position="upper_left", font_size=2)
    display.show(plotter, backend="none")
    assert plotting._shown == []


def test_corner_texts_keep_the_size_asked_for():
    """A corner annotation shrinks a long caption silently; show() pins it to a text actor of the asked size."""
    import numpy as np
    import pyvista as pv

    sizes = []
    for caption in ("short", "a much, much longer caption across the picture"):
        plotter = pv.Plotter(off_screen=True, window_size=(640, 300))
        plotter.background_color = "white"
        plotter.add_text(caption, position="upper_left", font_size=10, color="black")
        assert display.pin_corner_texts(plotter) == 1
        assert display.scene_texts(plotter) == [(caption, 20.0)]
        rows = np.nonzero((display.snapshot(plotter) < 128).all(axis=2).any(axis=1))[0]
        sizes.append(rows.max() - rows.min())
    assert abs(sizes[0] - sizes[1]) <= 4, f"caption heights differ: {sizes}"


def test_colliding_tick_labels_are_found():
    """Chapter 04's octree-leaf bars had their labels run into each other ("64128256512"): the report names them."""
    plotting.use_style(record=False)
    fig, ax = plt.subplots(figsize=(4, 3))
    sizes = [str(2**k) for k in range(1, 14)]
    ax.bar(sizes, range(13))
    pairs = plotting.overlapping_texts(fig)
    assert ("1024", "2048") in pairs or ("2048", "4096") in pairs, pairs
    ax.tick_params(axis="x", labelrotation=90)
    assert plotting.overlapping_texts(fig) == []


def test_every_corner_and_edge_text_is_pinned():
    """pyvista's eight corner and edge positions all become text actors, none lost (the edges were dropped once)."""
    import pyvista as pv

    positions = ["lower_left", "lower_right", "upper_left", "upper_right", "lower_edge", "right_edge", "left_edge",
                 "upper_edge"]
    plotter = pv.Plotter(off_screen=True, window_size=(400, 300))
    for name in positions:
        plotter.add_text(name, position=name, font_size=10)
    display.pin_corner_texts(plotter)
    assert sorted(text for text, _ in display.scene_texts(plotter)) == sorted(positions)
    plotter.close()
