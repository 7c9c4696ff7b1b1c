"""A notebook as one HTML file that is whole offline: maths, 3D views and pictures, nothing fetched from the web.

nbconvert's ``lab`` HTML template loads require.js, MathJax 2 and (when the notebook holds widget state) the
jupyter-widgets manager from CDNs: opened without a network, the maths shows as raw TeX. :func:`export_html`
writes the same page with

* **MathJax 3 inlined** -- its single-file ``tex-svg-full.js`` (from the ``django-static-mathjax`` package, MathJax
  3.2.2) goes into the page, and typesets to SVG, so no font files are needed either;
* **no require.js and no widget manager** -- csgnb's 3D views are self-contained vtk.js pages in ``<iframe
  srcdoc>`` (:mod:`csgnb.display`) and its pictures are embedded PNGs, so nothing in the page needs them. A widget
  output, which only a live kernel (or the CDN manager) can draw, shows its text representation; a progress bar
  (a finished run's live feedback, whose text would be its first, empty state) is left out;
* **no mermaid loader** (the chapters draw no mermaid diagrams; one that did would be refused, not left blank).

:func:`external_references` lists what a page would still fetch; :func:`export_html` refuses to write a page
that has any, so "offline" is checked each time, not assumed.

Command line (``scripts/demo.sh`` uses it)::

    python -m csgnb.offline_html notebooks/00_tour.ipynb --execute --output-dir out
"""

from __future__ import annotations

import argparse
import copy
import html
import re
import sys
from importlib import resources
from pathlib import Path

import nbformat

__all__ = ["export_html", "external_references", "mathjax_source", "main"]

_WIDGET_VIEW = "application/vnd.jupyter.widget-view+json"
_MATHJAX_FILE = "static/mathjax/es5/tex-svg-full.js"

# MathJax 3 configured as Jupyter's MathJax 2 is: $...$ and \(...\) inline, $$...$$ and \[...\] displayed, \$ for a
# dollar sign, environments such as align, AMS equation numbers.
_MATHJAX_CONFIG = """window.MathJax = {
  tex: {inlineMath: [['$', '$'], ['\\\\(', '\\\\)']], displayMath: [['$$', '$$'], ['\\\\[', '\\\\]']],
        processEscapes: true, processEnvironments: true, tags: 'ams'},
  svg: {fontCache: 'global'}
};"""

_TEMPLATE = """{%- extends 'index.html.j2' -%}
{%- block html_head_js_requirejs -%}{%- endblock html_head_js_requirejs -%}
{%- block jupyter_widgets -%}{%- endblock jupyter_widgets -%}
{%- block html_head_js_mermaidjs -%}{%- endblock html_head_js_mermaidjs -%}
{%- block html_head_js_mathjax -%}
<script>
{{ resources.csgnb_mathjax_config }}
</script>
<script>
{{ resources.csgnb_mathjax_source }}
</script>
{%- endblock html_head_js_mathjax -%}
"""

# What makes a browser fetch something: src attributes, <link href>, CSS url() and @import, JS import() and fetch().
# Anchors (<a href>: a link the reader may follow, not a load), data: URIs and URLs that appear in comments or
# strings of inline scripts (licence headers, documentation links) are not loads.
_LOADS = re.compile(
    r"""(?:\bsrc\s*=\s*["']?|<link\b[^>]*?\bhref\s*=\s*["']?|url\(\s*["']?|@import\s+["']|\bimport\(\s*["']"""
    r"""|\bfetch\(\s*["'])(?P<url>(?:https?:)?//[^"')\s>]+)""",
    re.IGNORECASE,
)


def mathjax_source() -> str:
    """Return MathJax 3's single-file TeX-to-SVG bundle (``es5/tex-svg-full.js``) as text.

    Raises ``FileNotFoundError`` with what to install when the ``django-static-mathjax`` package is missing.
    """
    try:
        return (resources.files("mathjax") / _MATHJAX_FILE).read_text(encoding="utf-8")
    except (ModuleNotFoundError, FileNotFoundError) as exc:
        raise FileNotFoundError(
            f"MathJax 3 ({_MATHJAX_FILE}) is not installed: `pip install django-static-mathjax` "
            "(scripts/setup.sh installs it from requirements.lock)") from exc


def external_references(page: str) -> list[str]:
    """Return the URLs a browser would fetch to show ``page`` (an HTML text), in order of appearance.

    Looks at the page and at the pages inlined in ``<iframe srcdoc>`` (HTML-escaped inside the attribute).
    Anchors, ``data:`` URIs and URLs that only appear in comments or strings are not fetches and are not listed.
    """
    found = [m.group("url") for m in _LOADS.finditer(page)]
    for srcdoc in re.finditer(r'srcdoc="([^"]*)"', page):
        found += external_references(html.unescape(srcdoc.group(1)))
    return found


def _progress_bar_ids(widget_state: dict) -> set[str]:
    """Ids of the widget models that are progress bars (a FloatProgress/IntProgress, or a box holding one)."""
    models = widget_state.get("state", {})

    def is_bar(model_id: str, depth: int = 0) -> bool:
        model = models.get(model_id)
        if model is None or depth > 8:
            return False
        if model.get("model_name") in ("FloatProgressModel", "IntProgressModel"):
            return True
        children = model.get("state", {}).get("children", [])
        return any(is_bar(str(c).removeprefix("IPY_MODEL_"), depth + 1) for c in children)

    return {model_id for model_id in models if is_bar(model_id)}


def _without_widgets(nb: nbformat.NotebookNode) -> nbformat.NotebookNode:
    """A copy of ``nb`` whose widget outputs show as text (progress bars dropped), and without widget state."""
    nb = copy.deepcopy(nb)
    state = nb.metadata.pop("widgets", {}).get("application/vnd.jupyter.widget-state+json", {})
    bars = _progress_bar_ids(state)
    for cell in nb.cells:
        outputs = []
        for out in cell.get("outputs", []):
            data = out.get("data", {})
            if _WIDGET_VIEW in data:
                if data[_WIDGET_VIEW].get("model_id") in bars or "text/plain" not in data:
                    continue
                del data[_WIDGET_VIEW]
            outputs.append(out)
        if "outputs" in cell:
            cell.outputs = outputs
    return nb


def _uses_mermaid(nb: nbformat.NotebookNode) -> bool:
    return any(cell.cell_type == "markdown" and "```mermaid" in cell.source for cell in nb.cells)


def export_html(notebook: str | Path, output_dir: str | Path, *, execute: bool = False,
                timeout: int = 1600) -> Path:
    """Write ``notebook`` as ``<output_dir>/<stem>.html``, a page that shows everything without a network.

    Parameters
    ----------
    notebook:
        Path of an ``.ipynb`` file.
    output_dir:
        Folder for the page (created if missing).
    execute:
        Run the notebook first (in its own folder, as Jupyter does), ``timeout`` seconds per cell; otherwise its
        stored outputs are used.

    Returns the path of the page. The page is written whole or not at all (a temporary file renamed into place).

    Raises ``ValueError`` if the page would still fetch something from the web (the URLs are named), or if the
    notebook draws mermaid diagrams (their renderer is not bundled); ``FileNotFoundError`` for a missing notebook
    or MathJax package; nbconvert's ``CellExecutionError`` when a cell fails under ``execute``.
    """
    from jinja2 import DictLoader
    from nbconvert import HTMLExporter
    from nbconvert.preprocessors import ExecutePreprocessor

    notebook = Path(notebook)
    if not notebook.is_file():
        raise FileNotFoundError(f"no notebook at {notebook}")
    nb = nbformat.read(notebook, as_version=4)
    if _uses_mermaid(nb):
        raise ValueError(f"{notebook} draws mermaid diagrams, whose renderer an offline page does not bundle")
    if execute:
        # the kernel at log level ERROR: its TCP-transport warning is not the reader's business
        ExecutePreprocessor(timeout=timeout, kernel_name="python3", extra_arguments=["--log-level=ERROR"]).preprocess(
            nb, {"metadata": {"path": str(notebook.parent.resolve())}})
    nb = _without_widgets(nb)

    exporter = HTMLExporter(template_name="lab", extra_loaders=[DictLoader({"csgnb_offline.html.j2": _TEMPLATE})],
                            template_file="csgnb_offline.html.j2")
    resources_in = {"metadata": {"name": notebook.stem},
                    "csgnb_mathjax_config": _MATHJAX_CONFIG,
                    "csgnb_mathjax_source": mathjax_source().replace("</script", "<\\/script")}
    page, _ = exporter.from_notebook_node(nb, resources=resources_in)
    fetched = external_references(page)
    if fetched:
        raise ValueError(f"the page of {notebook.name} would fetch {len(fetched)} resources from the web, "
                         f"so it is not offline: {sorted(set(fetched))[:5]}")

    output_dir = Path(output_dir)
    output_dir.mkdir(parents=True, exist_ok=True)
    target = output_dir / f"{notebook.stem}.html"
    partial = target.with_name(f".{target.name}.partial")
    partial.write_text(page, encoding="utf-8")
    partial.replace(target)
    return target


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m csgnb.offline_html",
        description="Write notebooks as HTML pages that show maths, 3D views and pictures without a network.")
    parser.add_argument("notebooks", nargs="+", type=Path, help=".ipynb files")
    parser.add_argument("--output-dir", type=Path, default=Path("out"), help="folder for the pages (default: out)")
    parser.add_argument("--execute", action="store_true", help="run each notebook first")
    parser.add_argument("--timeout", type=int, default=1600, help="seconds per cell under --execute")
    args = parser.parse_args(argv)
    for notebook in args.notebooks:
        try:
            page = export_html(notebook, args.output_dir, execute=args.execute, timeout=args.timeout)
        except (ValueError, FileNotFoundError) as exc:
            print(f"csgnb.offline_html: {exc}", file=sys.stderr)
            return 2
        print(f"wrote {page} ({page.stat().st_size / 1e6:.1f} MB, offline)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
