"""csgnb.offline_html: a notebook's HTML page shows its maths and outputs with the network cut off.

The browser checks open the pages in Debian's headless Chromium (as tests/test_notebooks_in_browser.py does) with
every request other than the page itself aborted and recorded: a page that is "offline" fetches nothing, and its
maths is typeset (MathJax's SVG output in place of every ``$...$``).
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import nbformat
import pytest

from csgnb.offline_html import _progress_bar_ids, export_html, external_references, main

ROOT = Path(__file__).resolve().parents[1]
CHROMIUM = os.environ.get("CSGNB_BROWSER", "/usr/bin/chromium")

BAR_STATE = {
    "state": {
        "box": {"model_name": "HBoxModel", "state": {"children": ["IPY_MODEL_label", "IPY_MODEL_bar"]}},
        "bar": {"model_name": "FloatProgressModel", "state": {"value": 6, "max": 6}},
        "label": {"model_name": "HTMLModel", "state": {"value": "kernels"}},
        "slider": {"model_name": "IntSliderModel", "state": {"value": 3}},
    },
    "version_major": 2, "version_minor": 0,
}


def _widget_output(model_id: str, text: str) -> nbformat.NotebookNode:
    return nbformat.v4.new_output("display_data", data={
        "application/vnd.jupyter.widget-view+json": {"model_id": model_id, "version_major": 2, "version_minor": 0},
        "text/plain": text})


def _notebook(tmp_path: Path, extra_markdown: str = "") -> Path:
    nb = nbformat.v4.new_notebook()
    nb.cells = [
        nbformat.v4.new_markdown_cell("# Maths\n\nInline $a^2 + b^2 = c^2$ and $x_1$, displayed\n\n"
                                      "$$\\sum_{i=1}^{n} \\frac{1}{i^2} \\le \\sqrt{3}$$\n\nA price of \\$5." +
                                      extra_markdown),
        nbformat.v4.new_code_cell("run()", outputs=[_widget_output("box", "kernels:   0%|   | 0/6"),
                                                    _widget_output("slider", "IntSlider(value=3)"),
                                                    nbformat.v4.new_output("stream", text="done\n")]),
    ]
    nb.metadata["widgets"] = {"application/vnd.jupyter.widget-state+json": BAR_STATE}
    path = tmp_path / "maths.ipynb"
    nbformat.write(nb, path)
    return path


def test_external_references_lists_loads_not_links():
    page = """<script src="https://cdn.example/require.js"></script><link rel="stylesheet" href="//cdn.example/a.css">
    <a href="https://www.mathjax.org">a link</a><img src="data:image/png;base64,AAAA"><a href="#top">top</a>
    <style>@import "https://fonts.example/f.css"; .x {background: url('https://img.example/b.png')}</style>
    <script>// see https://docs.example/page
    const m = await import("https://esm.example/m.mjs"); fetch('https://api.example/x');</script>
    <iframe srcdoc="&lt;script src=&quot;https://inner.example/vtk.js&quot;&gt;&lt;/script&gt;"></iframe>"""
    assert external_references(page) == [
        "https://cdn.example/require.js", "//cdn.example/a.css", "https://fonts.example/f.css",
        "https://img.example/b.png", "https://esm.example/m.mjs", "https://api.example/x",
        "https://inner.example/vtk.js"]


def test_progress_bars_are_found_through_their_boxes():
    assert _progress_bar_ids(BAR_STATE) == {"box", "bar"}


def test_page_has_no_external_reference_and_widgets_as_text(tmp_path):
    page = export_html(_notebook(tmp_path), tmp_path / "out").read_text()
    assert external_references(page) == []
    assert "cdnjs" not in page and "unpkg" not in page and "require.min.js" not in page
    assert "IntSlider(value=3)" in page, "a widget other than a progress bar shows its text"
    assert "0/6" not in page, "a progress bar's first state is left out"
    assert "widget-state+json" not in page and "widget-view+json" not in page
    assert "MathJax" in page and "$a^2 + b^2 = c^2$" in page


def test_refuses_a_page_that_would_fetch_and_writes_nothing(tmp_path):
    path = _notebook(tmp_path, '\n\n<img src="https://example.com/logo.png">')
    with pytest.raises(ValueError, match=r"would fetch 1 resources.*example\.com/logo\.png"):
        export_html(path, tmp_path / "out")
    assert not (tmp_path / "out").exists(), "nothing is written for a refused page"


def test_refuses_mermaid_and_missing_notebooks(tmp_path):
    with pytest.raises(ValueError, match="mermaid"):
        export_html(_notebook(tmp_path, "\n\n```mermaid\ngraph TD; A-->B\n```\n"), tmp_path / "out")
    with pytest.raises(FileNotFoundError, match="no notebook"):
        export_html(tmp_path / "missing.ipynb", tmp_path / "out")


def test_command_line_reports_a_refusal(tmp_path, capsys):
    assert main([str(tmp_path / "missing.ipynb"), "--output-dir", str(tmp_path)]) == 2
    assert "no notebook" in capsys.readouterr().err


def _open_offline(page_path: Path) -> dict:
    """Open ``page_path`` in headless Chromium with the network cut off; return what MathJax typeset and what the
    page tried to fetch."""
    if not Path(CHROMIUM).exists():
        pytest.fail(f"the offline check needs Debian's chromium at {CHROMIUM}: run `bash scripts/setup.sh` as root")
    from playwright.sync_api import sync_playwright

    requested: list[str] = []

    def route(r):
        if r.request.url.startswith(("file:", "data:", "about:")):
            r.continue_()
        else:
            requested.append(r.request.url)
            r.abort()

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, headless=True,
                                    args=["--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader"])
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 800})
            page.route("**/*", route)
            page.goto(page_path.resolve().as_uri(), timeout=60_000)
            page.wait_for_function("window.MathJax && MathJax.startup && MathJax.startup.promise", timeout=60_000)
            page.evaluate("MathJax.startup.promise")
            found = page.evaluate("""() => ({
              typeset: document.querySelectorAll('mjx-container').length,
              displayed: document.querySelectorAll('mjx-container[display="true"]').length,
              errors: document.querySelectorAll('mjx-merror').length,
              raw: Array.from(document.querySelectorAll('.jp-MarkdownOutput'))
                        .map((e) => e.innerText).filter((t) => /\\$[^$\\s][^$]*\\$/.test(t)),
              text: document.body.innerText})""")
        finally:
            browser.close()
    found["requested"] = requested
    return found


def test_maths_is_typeset_with_the_network_cut_off(tmp_path):
    found = _open_offline(export_html(_notebook(tmp_path), tmp_path / "out"))
    assert found["requested"] == []
    assert found["typeset"] == 3 and found["displayed"] == 1 and found["errors"] == 0
    assert found["raw"] == [], "TeX left untypeset"
    assert "price of $5" in found["text"], "an escaped dollar stays a dollar"


def test_the_tour_page_is_whole_offline(tmp_path):
    """The committed tour (its stored outputs: pictures, 3D views as they were committed) as the demo writes it."""
    tour = ROOT / "notebooks" / "00_tour.ipynb"
    markdown = "\n\n".join("".join(cell["source"]) for cell in json.loads(tour.read_text())["cells"]
                           if cell["cell_type"] == "markdown")
    spans = re.findall(r"\$\$.+?\$\$|(?<![\\$])\$[^$\n]+?\$", markdown, re.DOTALL)
    found = _open_offline(export_html(tour, tmp_path))
    assert found["requested"] == []
    assert found["errors"] == 0 and found["raw"] == []
    assert found["typeset"] == len(spans) > 0
