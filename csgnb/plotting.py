"""Figures a reader can read: csgnb's matplotlib style, and the size of the smallest text a reader sees.

A picture in a notebook is shown at its own pixel size, shrunk to the output area when it is wider. The narrowest
output area a reader has is :data:`READER_WIDTH_PX` wide (JupyterLab at 1280×800 with the file browser open), so
a figure of ``W`` pixels shows its text at ``min(1, READER_WIDTH_PX / W)`` times its rendered size: a 10-pt title on
a 17-inch-wide figure is 6 px on screen. Text must stay at least :data:`MIN_TEXT_PX` pixels there.

* :func:`use_style` applies ``csgnb.mplstyle`` (sizes chosen for figures up to :data:`READER_WIDTH_PX` wide,
  constrained layout so that labels do not collide) and starts recording every matplotlib figure a notebook
  shows, and every 3D scene :func:`csgnb.display.show` shows;
* :func:`text_sizes` measures one matplotlib figure: every text actually drawn, in on-screen pixels;
* :func:`legibility_report` says whether everything shown since :func:`use_style` is legible, and names the texts
  that are not. Each chapter ends with it in a checked cell (``# NBVAL_CHECK_OUTPUT``), so a figure whose text is
  too small fails the notebook's test.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
from pathlib import Path

__all__ = ["MIN_TEXT_PX", "READER_WIDTH_PX", "STYLE", "ShownText", "legibility_report", "record_scene",
           "text_sizes", "use_style"]

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


def text_sizes(fig, *, width_px: float = READER_WIDTH_PX) -> list[tuple[str, float]]:
    """Every text drawn in matplotlib figure ``fig`` with its on-screen size in pixels, ``[(text, px), ...]``.

    The figure is drawn once (Agg) and the texts that are really drawn are collected (a hidden axis' tick labels
    are not); its width is that of the tight bounding box, as Jupyter shows it, at ``fig.dpi``; a figure wider
    than ``width_px`` is shrunk to it.
    """
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
    shrink = min(1.0, width_px / max(width, 1.0))
    return [(t.get_text(), t.get_fontsize() * fig.dpi / 72.0 * shrink) for t in drawn]


def record_scene(texts_px: list[tuple[str, float]], window_width: int) -> None:
    """Record the texts of a 3D scene shown ``window_width`` pixels wide (``[(text, px at full size), ...]``); called
    by :func:`csgnb.display.show`. Nothing is recorded before :func:`use_style`."""
    if _recording:
        shrink = min(1.0, READER_WIDTH_PX / max(window_width, 1))
        _shown.append([ShownText(len(_shown) + 1, text, px * shrink) for text, px in texts_px])


_recording = False


def _record_figure(fig) -> None:
    _shown.append([ShownText(len(_shown) + 1, text, px) for text, px in text_sizes(fig)])


def use_style(*, record: bool = True) -> None:
    """Apply ``csgnb.mplstyle`` and (with ``record``) start recording the text sizes of what is shown.

    Matplotlib figures are measured when IPython displays them (the inline backend's PNG); outside IPython only
    the style is applied. Restarts the record.
    """
    import matplotlib.pyplot as plt

    global _recording
    plt.style.use(STYLE)
    _shown.clear()
    _recording = record
    if not record:
        return
    with contextlib.suppress(ImportError):
        from IPython import get_ipython

        shell = get_ipython()
        if shell is not None:
            from matplotlib.figure import Figure

            png = shell.display_formatter.formatters["image/png"]
            previous = png.lookup_by_type(Figure) if Figure in png.type_printers else None
            if previous is not None and getattr(previous, "_csgnb_records", False):
                previous = previous._csgnb_previous

            def measured(fig, _previous=previous):
                _record_figure(fig)
                return _previous(fig) if _previous is not None else None

            measured._csgnb_records = True
            measured._csgnb_previous = previous
            png.for_type(Figure, measured)


def legibility_report(min_px: float = MIN_TEXT_PX) -> str:
    """One line if every text shown since :func:`use_style` is at least ``min_px`` on screen; otherwise a line per
    figure with smaller text: how many of its texts are too small, and the smallest (what it says, its size)."""
    n_figures = len(_shown)
    small = [[t for t in figure if t.px < min_px - 1e-9] for figure in _shown]
    if not any(small):
        return (f"{n_figures} figures shown, every text at least {min_px:g} px on screen "
                f"(output area {READER_WIDTH_PX} px wide)")
    lines = [f"{sum(map(bool, small))} of {n_figures} figures have text under {min_px:g} px on screen "
             f"(output area {READER_WIDTH_PX} px wide):"]
    for figure, texts in zip(_shown, small, strict=True):
        if texts:
            worst = min(texts, key=lambda t: t.px)
            lines.append(f"  figure {worst.figure}: {len(texts)} of {len(figure)} texts, the smallest "
                         f"{worst.text[:50]!r} {worst.px:.1f} px")
    return "\n".join(lines)
