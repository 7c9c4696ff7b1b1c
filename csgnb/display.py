"""How the notebooks show 3D scenes: one call, a static picture or a view you can turn, chosen by environment.

:func:`show` takes a finished :class:`pyvista.Plotter` and returns what a notebook cell displays. The kind of
output follows pyvista's own variable ``PYVISTA_JUPYTER_BACKEND``:

* ``static`` -- a PNG. Deterministic: the set-up exports it for nbval and CI.
* ``html`` (the default when the variable is unset; ``scripts/lab.sh`` and ``scripts/demo.sh`` use it) -- the
  scene as a self-contained vtk.js page (pyvista's ``html`` backend, trame-vtk's exporter) in an
  ``<iframe srcdoc>``. Drag to rotate, scroll to zoom, in JupyterLab *and* in an HTML export: no server, no
  kernel, nothing fetched from the network. pyvista returns the same page inside an ``ipywidgets.HTML``;
  csgnb puts it in a plain ``text/html`` output instead, because an exported HTML file can only draw widgets
  with a script from a CDN. vtk.js draws scalar bars but not VTK's text actors, so the texts of the scene
  (``add_text``) are laid over each view as HTML.
* ``none`` -- nothing is shown (the PNG is still written when asked for).
* ``trame``, ``client``, ``server`` -- handed to ``Plotter.show`` (these need a running kernel and trame server).

:func:`show` builds IPython display objects itself instead of calling ``Plotter.show``, so it works inside an
``ipywidgets`` callback, where pyvista does not detect the notebook and ignores its backend.

:func:`aim` places the camera; :func:`add_legend` labels colours in a way both kinds of output show;
:func:`snapshot` renders to an image array (for composing pictures).
"""

from __future__ import annotations

import contextlib
import html
import io
import os
import tempfile
from pathlib import Path

import numpy as np

__all__ = ["BACKENDS", "add_legend", "aim", "jupyter_backend", "show", "snapshot"]

#: The values of ``PYVISTA_JUPYTER_BACKEND`` that :func:`show` understands.
BACKENDS = ("static", "html", "none", "trame", "client", "server")

_DEFAULT_BACKEND = "html"
_SERVED = ("trame", "client", "server")  # pyvista keeps serving these plotters: not closed here


def jupyter_backend(backend: str | None = None) -> str:
    """Return the backend :func:`show` uses: ``backend`` if given, else ``PYVISTA_JUPYTER_BACKEND``, else ``html``.

    Raises ``ValueError`` for a name that is not in :data:`BACKENDS`.
    """
    name = backend if backend is not None else os.environ.get("PYVISTA_JUPYTER_BACKEND", "").strip()
    name = (name or _DEFAULT_BACKEND).lower()
    if name not in BACKENDS:
        source = "backend" if backend is not None else "PYVISTA_JUPYTER_BACKEND"
        raise ValueError(f"{source}={name!r} is not a backend csgnb.display.show knows; use one of {BACKENDS}")
    return name


def aim(plotter, focus=None, distance: float | None = None, direction=(1.0, -2.0, 0.9), up=(0.0, 0.0, 1.0), *,
        bounds=None, margin: float = 0.06) -> None:
    """Point the camera of ``plotter`` (its active subplot) along ``direction``, at ``focus`` from ``distance``.

    With ``distance`` given, the camera sits at ``focus + distance * direction / |direction|``: one fixed camera
    per scene, so that the pictures of a sequence line up.

    Without it (the usual call: ``aim(plotter)`` or ``aim(plotter, direction=...)``), the camera is *fitted*: what
    the subplot shows (the points of its visible meshes), or the box ``bounds`` (``(xmin, xmax, ymin, ymax, zmin,
    zmax)``) when given, is centred in the picture and fills it but for ``margin`` (a fraction of the half-width) on
    its tightest side, in perspective and for the subplot's aspect ratio. ``focus``, if given, stays the focal point.
    Give ``bounds`` for a sequence of pictures that must line up.

    Raises ``ValueError`` for a zero or non-finite direction, an up vector parallel to it, or empty bounds.
    """
    d = np.asarray(direction, float).reshape(3)
    norm = np.linalg.norm(d)
    if not np.isfinite(norm) or norm == 0:
        raise ValueError(f"aim needs a non-zero, finite direction, got {direction!r}")
    d = d / norm
    up = np.asarray(up, float).reshape(3)
    if distance is None:
        points = _scene_points(plotter.renderer) if bounds is None else None
        if points is None:
            box = np.asarray(plotter.renderer.ComputeVisiblePropBounds() if bounds is None else bounds, float)
            if box.shape != (6,) or not np.all(np.isfinite(box)) or np.any(box[1::2] < box[0::2]):
                raise ValueError(f"aim needs finite bounds (xmin, xmax, ymin, ymax, zmin, zmax) to fit, got {box}")
            points = np.array(np.meshgrid(box[0:2], box[2:4], box[4:6], indexing="ij")).reshape(3, -1).T
        focus, distance = _fit(plotter, points, d, up, focus, margin)
    focus = np.asarray(focus, float).reshape(3)
    plotter.camera.focal_point = tuple(focus)
    plotter.camera.position = tuple(focus + float(distance) * d)
    plotter.camera.up = tuple(float(u) for u in up)


def _scene_points(renderer, most: int = 200_000) -> np.ndarray | None:
    """The points of the visible meshes of ``renderer``, ``(n, 3) float``, at most ``most`` of them (an even
    subsample of each mesh beyond that); ``None`` when it shows no points."""
    import pyvista as pv

    chunks = []
    for actor in renderer.GetActors():
        mapper = actor.GetMapper()
        data = mapper.GetInput() if actor.GetVisibility() and mapper is not None else None
        if data is None or data.GetNumberOfPoints() == 0:
            continue
        pts = np.asarray(pv.wrap(data).points, float)
        if actor.GetUserMatrix() is not None or not np.allclose(actor.GetPosition(), 0):
            matrix = pv.array_from_vtkmatrix(actor.GetMatrix())
            pts = pts @ matrix[:3, :3].T + matrix[:3, 3]
        chunks.append(pts)
    total = sum(len(c) for c in chunks)
    if total == 0:
        return None
    step = max(1, total // most)
    return np.concatenate([c[::step] for c in chunks])


def _fit(plotter, corners: np.ndarray, d: np.ndarray, up: np.ndarray, focus, margin: float):
    """Focal point and distance along ``d`` at which ``corners`` (``(n, 3)`` points) fill the subplot's view,
    centred."""
    right = np.cross(-d, up)
    if np.linalg.norm(right) < 1e-12 * np.linalg.norm(up):
        raise ValueError(f"aim: the up vector {tuple(up)} is parallel to the view direction {tuple(d)}")
    right /= np.linalg.norm(right)
    true_up = np.cross(right, -d)
    x0, y0, x1, y1 = plotter.renderer.GetViewport()
    width, height = (x1 - x0) * plotter.window_size[0], (y1 - y0) * plotter.window_size[1]
    tan_y = np.tan(np.radians(plotter.camera.view_angle) / 2) * (1 - margin)
    tan_x = tan_y * width / height
    if focus is None:
        centre = (corners.min(axis=0) + corners.max(axis=0)) / 2
    else:
        centre = np.asarray(focus, float).reshape(3)
    size = max(float(np.ptp(corners, axis=0).max()), 1e-12)
    for step in range(4):
        rel = corners - centre
        x, y, z = rel @ right, rel @ true_up, rel @ d
        distance = max(float(np.max(z + np.abs(x) / tan_x)), float(np.max(z + np.abs(y) / tan_y)), size * 1e-3)
        if focus is not None or step == 3:
            break
        # centre the corners' angular extent: move the focal point across the view by the midpoint of the extent
        depth = distance - z
        sx, sy = x / depth, y / depth
        centre = centre + distance * ((sx.max() + sx.min()) / 2 * right + (sy.max() + sy.min()) / 2 * true_up)
    return centre, distance


def add_legend(plotter, entries, *, font_size: int = 12, corner: str = "upper right") -> None:
    """Label colours in the active subplot of ``plotter``: one line per ``(label, colour)``, on a swatch of it.

    ``corner`` is ``"upper right"``, ``"upper left"``, ``"lower right"`` or ``"lower left"``. Plain text actors,
    so the legend shows in the static picture and over the interactive view alike (vtk.js draws no VTK legend).
    """
    import pyvista as pv

    if corner not in ("upper right", "upper left", "lower right", "lower left"):
        raise ValueError(f"corner must be 'upper right', 'upper left', 'lower right' or 'lower left', got {corner!r}")
    entries = list(entries)
    renderer = plotter.renderer
    x0, y0, x1, y1 = renderer.GetViewport()
    w, h = (x1 - x0) * plotter.window_size[0], (y1 - y0) * plotter.window_size[1]
    step = 1.9 * font_size
    right, top = corner.endswith("right"), corner.startswith("upper")
    for k, (label, colour) in enumerate(entries):
        rgb = pv.Color(colour).float_rgb
        light = 0.299 * rgb[0] + 0.587 * rgb[1] + 0.114 * rgb[2] > 0.55
        y = h - 10 - k * step if top else 10 + (len(entries) - 1 - k) * step
        actor = plotter.add_text(str(label), position=(w - 10 if right else 10, y), font_size=font_size,
                                 color="black" if light else "white")
        prop = actor.GetTextProperty()
        prop.SetJustification(2 if right else 0)
        prop.SetVerticalJustification(2 if top else 0)
        prop.SetBackgroundColor(rgb)
        prop.SetBackgroundOpacity(1.0)


def snapshot(plotter, path: str | Path | None = None, *, close: bool = True, record: bool = True) -> np.ndarray:
    """Render ``plotter`` off screen and return the picture, ``(h, w, 3) uint8``; also write it to ``path`` if given.

    Corner texts are pinned to their asked size first (:func:`pin_corner_texts`), and with ``record`` the scene's
    texts are recorded for :func:`csgnb.plotting.legibility_report` (a picture made for a widget is shown too).
    Closes the plotter unless ``close=False``.
    """
    pin_corner_texts(plotter)
    if record:
        from csgnb import plotting

        plotting.record_scene(scene_texts(plotter), int(plotter.window_size[0]))
    image = plotter.screenshot(str(path) if path is not None else None, return_img=True)
    if close:
        plotter.close()
    return np.asarray(image)


def show(plotter, path: str | Path | None = None, *, backend: str | None = None):
    """Return the display object for ``plotter`` under the current backend (see the module docstring).

    Parameters
    ----------
    plotter : pyvista.Plotter
        A finished scene; it is closed afterwards.
    path : str or Path, optional
        Also write the scene as a PNG there (whatever the backend), e.g. for the pictures under ``out/``.
    backend : str, optional
        Overrides ``PYVISTA_JUPYTER_BACKEND`` (one of :data:`BACKENDS`).

    Returns
    -------
    IPython.display.Image, IPython.display.HTML, or None
        Display it, or let it be the value of the cell.
    """
    from IPython.display import HTML, Image

    from csgnb import plotting

    name = jupyter_backend(backend)
    if plotter.render_window is None:
        raise ValueError("this plotter is closed; build the scene again before showing it")
    pin_corner_texts(plotter)
    plotting.record_scene(scene_texts(plotter), int(plotter.window_size[0]))
    png = None
    if path is not None or name == "static":
        png = _png(snapshot(plotter, path, close=False, record=False))
    try:
        if name == "static":
            return Image(data=png, format="png")
        if name == "none":
            return None
        if name == "html":
            return HTML(_scene_html(plotter))
        plotter.notebook = True  # as in a callback, pyvista must not second-guess where it runs
        return plotter.show(jupyter_backend=name, return_viewer=True)
    finally:
        if name not in _SERVED:
            plotter.close()


# vtkCornerAnnotation slots (0 lower left, 1 lower right, 2 upper left, 3 upper right; 4 lower, 5 right, 6 left and
# 7 upper edge: pyvista's positions) as (x, y) in the viewport (a fraction of its size), and the horizontal and
# vertical justification (0 left/bottom, 1 centre, 2 right/top) that anchors the text there.
_CORNER_ANCHORS = {0: ((0.0, 0.0), 0, 0), 1: ((1.0, 0.0), 2, 0), 2: ((0.0, 1.0), 0, 2), 3: ((1.0, 1.0), 2, 2),
                   4: ((0.5, 0.0), 1, 0), 5: ((1.0, 0.5), 2, 1), 6: ((0.0, 0.5), 0, 1), 7: ((0.5, 1.0), 1, 2)}
_CORNER_INSET_PX = 6


def pin_corner_texts(plotter) -> int:
    """Replace the corner texts of ``plotter`` (pyvista's ``add_text(position="upper_left")`` and the like) by plain
    text actors of the size asked for; return how many were replaced.

    A corner annotation shrinks its font as its text grows, so a long caption ends up a few pixels high with no
    warning; a text actor keeps the size given (pyvista's ``font_size`` doubled, as ``add_text`` does with a
    position in pixels). :func:`show` calls it, so every shown scene has text of a known size.
    """
    import vtk

    replaced = 0
    for renderer in plotter.renderers:
        x0, y0, x1, y1 = renderer.GetViewport()
        vw, vh = (x1 - x0) * plotter.window_size[0], (y1 - y0) * plotter.window_size[1]
        for prop in _props(renderer):
            if not (prop.IsA("vtkCornerAnnotation") and prop.GetVisibility()):
                continue
            size = int(round(4 * prop.GetLinearFontScaleFactor()))  # pyvista: factor = font_size // 2
            for slot, ((fx, fy), horizontal, vertical) in _CORNER_ANCHORS.items():
                text = prop.GetText(slot)
                if not text:
                    continue
                actor = vtk.vtkTextActor()
                actor.SetInput(text)
                tp = actor.GetTextProperty()
                tp.ShallowCopy(prop.GetTextProperty())
                tp.SetFontSize(size)
                tp.SetJustification(horizontal)
                tp.SetVerticalJustification(vertical)
                inset = np.array([1 - 2 * fx, 1 - 2 * fy]) * _CORNER_INSET_PX
                actor.SetPosition(fx * vw + inset[0], fy * vh + inset[1])
                renderer.AddViewProp(actor)
            renderer.RemoveViewProp(prop)
            replaced += 1
    return replaced


def scene_texts(plotter) -> list[tuple[str, float]]:
    """The 2D texts of ``plotter`` with their font size in pixels at the window's size, ``[(text, px), ...]``.

    A text actor's font is its property's size (measured: a capital letter is 0.72 of it, as in DejaVu Sans);
    corner annotations are not measured (their size depends on their text): :func:`pin_corner_texts` first.
    """
    out = []
    for renderer in plotter.renderers:
        for prop in _props(renderer):
            if prop.GetVisibility() and prop.IsA("vtkTextActor") and str(prop.GetInput() or "").strip():
                out.append((str(prop.GetInput()), float(prop.GetTextProperty().GetFontSize())))
    return out


# --- the html backend -------------------------------------------------------------------------------------------


def _png(image: np.ndarray) -> bytes:
    from PIL import Image as PILImage

    buffer = io.BytesIO()
    PILImage.fromarray(np.asarray(image, np.uint8)).save(buffer, format="png")
    return buffer.getvalue()


def _offline_wasm_dir() -> None:
    # trame-vtklocal (pulled in by trame-pyvista) downloads a wasm bundle when its server starts unless this
    # variable names a directory; csgnb never uses it, so an empty one keeps everything offline.
    if not os.environ.get("VTK_WASM_DIR_OVERRIDE"):
        os.environ["VTK_WASM_DIR_OVERRIDE"] = tempfile.mkdtemp(prefix="csgnb-no-wasm-")


def _vtkjs_page(plotter) -> str:
    _offline_wasm_dir()
    try:
        component = plotter.trame
    except (AttributeError, ImportError) as err:  # pragma: no cover - depends on the installation
        raise ImportError("the 'html' backend needs trame-pyvista (pip install 'trame-pyvista[jupyter]'), "
                          "or set PYVISTA_JUPYTER_BACKEND=static") from err
    with contextlib.redirect_stdout(io.StringIO()):  # the trame server it starts announces itself on stdout
        return component.export_html(None).getvalue()


def _css_colour(rgba) -> str:
    r, g, b = (int(round(255 * float(c))) for c in rgba[:3])
    return f"rgb({r},{g},{b})"


def _format(fmt: str, value: float) -> str:
    try:
        text = fmt.format(value) if "{" in fmt else fmt % value
    except (ValueError, TypeError):
        text = f"{value:.3g}"
    return text.strip()


def _props(renderer):
    props = renderer.GetViewProps()
    props.InitTraversal()
    return [props.GetNextProp() for _ in range(props.GetNumberOfItems())]


def _captions(plotter, width: int, height: int) -> list[str]:
    """The scene's 2D texts as absolutely placed HTML, one per text, in the viewport of its subplot (corner texts
    are text actors by now: :func:`show` pins them first)."""
    out = []
    for renderer in plotter.renderers:
        x0, y0, x1, y1 = renderer.GetViewport()
        box = (f"position:absolute;left:{100 * x0:.3f}%;top:{100 * (1 - y1):.3f}%;width:{100 * (x1 - x0):.3f}%;"
               f"height:{100 * (y1 - y0):.3f}%;pointer-events:none")
        texts = []
        for prop in _props(renderer):
            if prop.GetVisibility() and prop.IsA("vtkTextActor"):
                x, y = prop.GetPosition()
                vw, vh = max((x1 - x0) * width, 1), max((y1 - y0) * height, 1)
                tp = prop.GetTextProperty()
                # Honour the text's justification: its anchor is a left/centre/right, bottom/centre/top point.
                dx = {0: 0, 1: -50, 2: -100}[tp.GetJustification()]
                dy = {0: 0, 1: 50, 2: 100}[tp.GetVerticalJustification()]
                where = (f"left:{100 * x / vw:.2f}%;bottom:{100 * y / vh:.2f}%;"
                         f"transform:translate({dx}%,{dy}%)")
                texts.append((where, prop.GetInput(), tp))
        if texts:
            spans = []
            for where, text, prop in texts:
                size = max(12, int(round(0.85 * prop.GetFontSize())))  # font size in pixels (pyvista doubled it)
                colour = _css_colour(prop.GetColor())
                style = f"position:absolute;{where};font:{size}px sans-serif;color:{colour};white-space:pre"
                if prop.GetBackgroundOpacity() > 0:
                    style += f";background:{_css_colour(prop.GetBackgroundColor())};padding:0 5px;line-height:1.1"
                spans.append(f'<div style="{style}">{html.escape(str(text))}</div>')
            out.append(f'<div style="{box}">{"".join(spans)}</div>')
    return out


def _scene_html(plotter) -> str:
    width, height = (int(v) for v in plotter.window_size)
    page = _vtkjs_page(plotter)  # before the overlays are read: export renders the scene
    frame = (f'<iframe class="csgnb-scene" title="3D view: drag to rotate, scroll to zoom" '
             f'srcdoc="{html.escape(page, quote=True)}" '
             f'style="position:absolute;left:0;top:0;width:100%;height:100%;border:1px solid #ddd"></iframe>')
    # At most the window's size, narrower when the output area is: the view shrinks with it and keeps its aspect
    # (a fixed width was cut off in a narrow notebook), as a picture does.
    view = (f'<div style="position:relative;width:100%;max-width:{width}px;aspect-ratio:{width}/{height};'
            f'flex:none">{frame}{"".join(_captions(plotter, width, height))}</div>')
    hint = ('<div style="font:12px sans-serif;color:#666;margin-top:2px">3D view: drag to rotate, '
            'shift-drag to pan, scroll to zoom</div>')
    return f'<div class="csgnb-view">{view}{hint}</div>'
