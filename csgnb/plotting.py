"""Figures a reader can read: csgnb's matplotlib style, and the size of the smallest text a reader sees.

A picture in a notebook is shown at its own pixel size, shrunk to the output area when it is wider. The narrowest
output area a reader has is :data:`READER_WIDTH_PX` wide (JupyterLab at 1280×800 with the file browser open), so
a figure of ``W`` pixels shows its text at ``min(1, READER_WIDTH_PX / W)`` times its rendered size: a 10-pt title on
a 17-inch-wide figure is 6 px on screen. Text must stay at least :data:`MIN_TEXT_PX` pixels there.

* :func:`use_style` applies ``csgnb.mplstyle`` (sizes chosen for figures up to :data:`READER_WIDTH_PX` wide,
  constrained layout so that labels do not collide) and starts recording every matplotlib figure a notebook
  shows (rendered into memory: the inline backend, or a picture's bytes for a widget), and every 3D scene
  :func:`csgnb.display.show` shows;
* :func:`text_sizes` measures one matplotlib figure: every text actually drawn, in on-screen pixels;
* :func:`legibility_report` says whether everything shown since :func:`use_style` is legible, and names the texts
  that are not. Each chapter ends with it in a checked cell (``# NBVAL_CHECK_OUTPUT``), so a figure whose text is
  too small fails the notebook's test.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

__all__ = ["MIN_TEXT_PX", "READER_WIDTH_PX", "STYLE", "ShownText", "legibility_report", "overlapping_texts",
           "record_scene", "text_sizes", "use_style"]

#: Width in pixels of the narrowest notebook output area a reader has (measured by the browser test).
READER_WIDTH_PX = 848
#: The smallest text, in on-screen pixels, that counts as legible.
MIN_TEXT_PX = 11.0
#: csgnb's matplotlib style file.
STYLE = Path(__file__).with_name("csgnb.mplstyle")


@dataclass(frozen=True)
class ShownText:
    """One text of a shown figure: which figure (``figure``, counted from 1 in the order shown), what it says, and
    its height on screen in pixels (the font size at the figure's resolution, shrunk as the picture is)."""

    figure: int
    text: str
    px: float


_shown: list[list[ShownText]] = []  # one list per figure shown since use_style()
_collisions: list[tuple[int, str, str]] = []  # (figure, text, text) whose boxes overlap
_recording = False  # set by use_style()


def _drawn_texts(fig, width_px: float):
    """Draw ``fig`` once (Agg); return the texts really drawn, the renderer and the factor the reader's output area
    shrinks the picture by (its tight bounding box at ``fig.dpi``, as Jupyter shows it, against ``width_px``)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.text import Text

    drawn: list[Text] = []
    original = Text.draw

    def spy(self, renderer):
        if self.get_visible() and self.get_text().strip():
            drawn.append(self)
        return original(self, renderer)

    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    Text.draw = spy
    try:
        canvas.draw()
    finally:
        Text.draw = original
    renderer = canvas.get_renderer()
    width = fig.get_tightbbox(renderer).width * fig.dpi
    return drawn, renderer, min(1.0, width_px / max(width, 1.0))


def text_sizes(fig, *, width_px: float = READER_WIDTH_PX) -> list[tuple[str, float]]:
    """Every text drawn in matplotlib figure ``fig`` with its on-screen size in pixels, ``[(text, px), ...]``.

    Only texts really drawn count (a hidden axis' tick labels do not); a figure wider than ``width_px`` is shrunk
    to it, and its text with it.
    """
    drawn, _, shrink = _drawn_texts(fig, width_px)
    return [(t.get_text(), _on_screen_px(t, fig, shrink)) for t in drawn]


def _on_screen_px(text, fig, shrink: float) -> float:
    """A matplotlib text's font size in pixels as shown: points at the figure's dpi, shrunk with the picture."""
    return text.get_fontsize() * fig.dpi / 72.0 * shrink


def overlapping_texts(fig, *, min_overlap_px: float = 1.0) -> list[tuple[str, str]]:
    """Pairs of texts drawn in ``fig`` whose boxes overlap by more than ``min_overlap_px`` in both directions
    (colliding tick labels, a label over a title), ``[(text, text), ...]``."""
    drawn, renderer, _ = _drawn_texts(fig, READER_WIDTH_PX)
    return _overlaps(drawn, renderer, min_overlap_px)


def _overlaps(drawn, renderer, min_overlap_px: float = 1.0) -> list[tuple[str, str]]:
    import numpy as np

    if len(drawn) < 2:
        return []
    boxes = np.array([t.get_window_extent(renderer).extents for t in drawn])  # x0, y0, x1, y1
    dx = np.minimum(boxes[:, None, 2], boxes[None, :, 2]) - np.maximum(boxes[:, None, 0], boxes[None, :, 0])
    dy = np.minimum(boxes[:, None, 3], boxes[None, :, 3]) - np.maximum(boxes[:, None, 1], boxes[None, :, 1])
    i, j = np.nonzero(np.triu((dx > min_overlap_px) & (dy > min_overlap_px), k=1))
    return [(drawn[a].get_text(), drawn[b].get_text()) for a, b in zip(i, j, strict=True)]


def record_scene(texts_px: list[tuple[str, float]], window_width: int) -> None:
    """Record the texts of a 3D scene shown ``window_width`` pixels wide (``[(text, px at full size), ...]``); called
    by :func:`csgnb.display.show`. Nothing is recorded before :func:`use_style`."""
    if _recording:
        shrink = min(1.0, READER_WIDTH_PX / max(window_width, 1))
        _shown.append([ShownText(len(_shown) + 1, text, px * shrink) for text, px in texts_px])



def _record_figure(fig) -> None:
    drawn, renderer, shrink = _drawn_texts(fig, READER_WIDTH_PX)
    number = len(_shown) + 1
    _shown.append([ShownText(number, t.get_text(), _on_screen_px(t, fig, shrink)) for t in drawn])
    _collisions.extend((number, a, b) for a, b in _overlaps(drawn, renderer))


def use_style(*, record: bool = True) -> None:
    """Apply ``csgnb.mplstyle`` and (with ``record``) start recording the text sizes of what is shown.

    A matplotlib figure is measured when it is rendered into memory -- Jupyter's inline backend showing it, or a
    notebook making the bytes of a picture for a widget -- not when it is saved to a file. Restarts the record.
    """
    import matplotlib.pyplot as plt

    global _recording
    plt.style.use(STYLE)
    _shown.clear()
    _collisions.clear()
    _recording = record
    if record:
        _watch_print_figure()


def _watch_print_figure() -> None:
    """Wrap ``FigureCanvasBase.print_figure`` (once) so that figures rendered to a buffer are recorded."""
    import os

    from matplotlib.backend_bases import FigureCanvasBase

    original = FigureCanvasBase.print_figure
    if getattr(original, "_csgnb_records", False):
        return

    def print_figure(self, filename, *args, **kwargs):
        if _recording and not isinstance(filename, str | os.PathLike):
            _record_figure(self.figure)
        return original(self, filename, *args, **kwargs)

    print_figure._csgnb_records = True
    FigureCanvasBase.print_figure = print_figure


def legibility_report(min_px: float = MIN_TEXT_PX) -> str:
    """One line if every text shown since :func:`use_style` is at least ``min_px`` on screen and no two texts of a
    matplotlib figure overlap; otherwise a line per figure with smaller text (how many, and the smallest) and a
    line per pair of colliding texts."""
    n_figures = len(_shown)
    small = [[t for t in figure if t.px < min_px - 1e-9] for figure in _shown]
    if not any(small) and not _collisions:
        return (f"{n_figures} figures shown, every text at least {min_px:g} px on screen "
                f"(output area {READER_WIDTH_PX} px wide), no texts overlap")
    lines = [f"{sum(map(bool, small))} of {n_figures} figures have text under {min_px:g} px on screen "
             f"(output area {READER_WIDTH_PX} px wide); {len(_collisions)} pairs of texts overlap:"]
    for figure, texts in zip(_shown, small, strict=True):
        if texts:
            worst = min(texts, key=lambda t: t.px)
            lines.append(f"  figure {worst.figure}: {len(texts)} of {len(figure)} texts, the smallest "
                         f"{worst.text[:50]!r} {worst.px:.1f} px")
    lines += [f"  figure {number}: {a[:30]!r} overlaps {b[:30]!r}" for number, a, b in _collisions]
    return "\n".join(lines)
