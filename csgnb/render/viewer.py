"""An interactive notebook viewer: drag to orbit, wheel to zoom, splats next to the reference.

The image is an ``ipywidgets.Image`` re-rendered on every (throttled) mouse move while a button
is held; mouse events come from ``ipyevents`` (sliders for azimuth, elevation and zoom work
everywhere, also without it). With a reference (``shape=`` or ``reference=True``) the viewer
shows splats, the ray-traced reference and their difference side by side; the slower reference
is re-rendered when the drag ends.
"""

from __future__ import annotations

import html
import time

from csgnb.errors import GeometryError
from csgnb.render.agreement import compare
from csgnb.render.camera import Camera
from csgnb.render.frame import Frame
from csgnb.render.level_of_detail import LevelChooser, LevelsOfDetail
from csgnb.render.raytracer import raytrace
from csgnb.render.scene import check_same_shape
from csgnb.render.splats import renderer_for

__all__ = ["Viewer"]

#: Degrees of orbit per pixel of drag.
DRAG_DEGREES = 0.4
#: Steps of the zoom slider per doubling of the zoom: the slider holds whole steps, the zoom is 2 ** (steps / 20).
ZOOM_STEPS = 20
#: Zoom slider steps per wheel notch (2 ** (3 / 20): x1.11 a notch), bounded by the slider's range.
WHEEL_STEPS = 3

# Why every slider holds whole numbers: the browser's slider (ipywidgets 8 on noUiSlider) turns a value set from
# Python into its own position and back, and sends the result back as if the user had moved it wherever the two
# differ. For a float slider they differ by rounding (elevation 30 came back as 30.000000000000014, a log slider's
# every value came back): each angle a drag set came back as one more full render with the reference, and a value
# set before a queued drag came back *after* it, turning the view to where it had been. An integer slider rounds
# what it reads and sends nothing when that is the value it was given (checked in a real browser:
# tests/test_notebooks_in_browser.py::test_the_viewer_s_sliders_send_back_nothing_python_set).


def _whole(slider, value: float) -> int:
    """``value`` rounded to a whole number within ``slider``'s range: a value the slider keeps as it is."""
    return int(min(slider.max, max(slider.min, round(float(value)))))


class Viewer:
    """Interactive splat viewer of a SampleCloud in a notebook.

    Parameters
    ----------
    cloud : SampleCloud
    camera : Camera or None — initial view (default: ``Camera.fit`` of the cloud at ``size``).
    shape : CSG node / NormalForm or None — show the reference ray tracer and the difference too
        (GeometryError if the cloud was sampled from another shape); ``reference=True`` uses the
        cloud's own normal form.
    size : (width, height) of each image.
    lod : bool or None — draw, per view, the level of detail whose splats are about ``TARGET_FOOTPRINT_PX`` (12)
        pixels on screen (:class:`~csgnb.render.level_of_detail.LevelsOfDetail`: clouds of the same surface at radii
        ``cloud.radius · √2^k``, sampled on first use and kept); where that is finer than ``cloud``, the faster of
        the two as measured over the first frames (:class:`~csgnb.render.level_of_detail.LevelChooser`). Every
        level draws the reference picture pixel for pixel, in less time where ``cloud``'s splats are small on screen
        or mostly clipped. Default (None): on without a reference,
        off with one -- the difference then checks ``cloud`` itself (a cloud with holes, e.g. thinned, must show
        them, not a resampled level's picture). True / False force it.
    render options (``footprint``, ``backface_culling``, ``color_by``, ``fallback``, ...) go to ``render``; with a
    reference every tile is splatted (``fallback="never"``) unless they say otherwise, so that the difference
    checks the splats, not the ray tracer against itself.

    ``viewer.azimuth`` / ``viewer.elevation`` are integer sliders in whole degrees, ``viewer.zoom`` one in steps of
    2^(1/20) (``viewer.zoom_factor`` is the zoom they set; see the module's note on whole numbers).
    ``viewer.widget`` is the ipywidgets box; displaying the viewer shows it. ``viewer.frame`` is
    the last splat frame, ``viewer.frame_ms`` its render time, ``viewer.drawn`` the cloud it drew (``cloud`` or a
    level of detail, ``viewer.levels``; ``viewer.level`` its level, ``viewer.chooser`` what chose it).
    """

    def __init__(self, cloud, camera: Camera | None = None, *, shape=None, reference: bool = False,
                 size=(640, 480), lod: bool | None = None, **options) -> None:
        import ipywidgets as widgets

        self.cloud = cloud
        self.drawn = cloud
        self.reference_shape = None
        if shape is not None:
            self.reference_shape = check_same_shape(cloud, shape)
        elif reference:
            self.reference_shape = cloud.normal_form
        if lod is None:
            lod = self.reference_shape is None
        self.levels = LevelsOfDetail(cloud, finer=True) if lod else None
        self.chooser = LevelChooser(self.levels) if lod else None
        self.level = 0
        w, h = size
        self.camera = camera.with_size(w, h) if camera is not None else Camera.fit(cloud, w, h)
        self.options = options if self.reference_shape is None else {"fallback": "never", **options}
        self.frame = None
        self.frame_ms = 0.0
        layout = widgets.Layout(width=f"{w}px", height=f"{h}px")
        self.image = widgets.Image(format="jpeg", layout=layout)
        images = [self.image]
        if self.reference_shape is not None:
            self.reference_image = widgets.Image(format="jpeg", layout=layout)
            self.difference_image = widgets.Image(format="png", layout=layout)
            images += [self.reference_image, self.difference_image]
        self.label = widgets.HTML()
        slider = dict(continuous_update=True, layout=widgets.Layout(width="32%"))
        self.azimuth = widgets.IntSlider(min=-180, max=180, description="azimuth", **slider)
        self.elevation = widgets.IntSlider(min=-89, max=89, description="elevation", **slider)
        self._syncing = False
        self._show_angles()
        # zoom x1/4 .. x8 in whole steps; its readout shows the factor, not the steps
        self.zoom = widgets.IntSlider(value=0, min=-2 * ZOOM_STEPS, max=3 * ZOOM_STEPS, description="zoom",
                                      readout=False, continuous_update=True, layout=widgets.Layout(width="26%"))
        self.zoom_readout = widgets.Label(layout=widgets.Layout(width="6%"))
        self._show_zoom()
        self._base = self.camera
        for s in (self.azimuth, self.elevation, self.zoom):
            s.observe(self._on_slider, names="value")
        self.widget = widgets.VBox([widgets.HBox(images),
                                    widgets.HBox([self.azimuth, self.elevation, self.zoom, self.zoom_readout]),
                                    self.label])
        self.events = None
        try:
            from ipyevents import Event
        except ImportError:  # pragma: no cover - ipyevents is a dependency; sliders still work
            self.label.value = "(install ipyevents to drag; sliders work)"
        else:
            self.events = Event(source=self.image, watched_events=["mousedown", "mouseup", "mousemove", "mouseleave",
                                                                    "wheel"],
                                prevent_default_action=True, throttle_or_debounce="throttle", wait=15)
            self.events.on_dom_event(self._on_event)
        self._drag = None
        self.update(reference=True)

    # -- rendering -------------------------------------------------------------------------------
    @property
    def renderer(self):
        """The SplatRenderer of the cloud drawn last (``drawn``)."""
        return renderer_for(self.drawn)

    def _angles(self) -> tuple[float, float]:
        import math

        import numpy as np

        from csgnb.render.camera import _plane_axes

        up = self.camera.up / np.linalg.norm(self.camera.up)
        off = self.camera.eye - self.camera.target
        x, y = _plane_axes(up)
        az = math.degrees(math.atan2(float(off @ y), float(off @ x)))
        el = math.degrees(math.asin(max(-1.0, min(1.0, float(off @ up) / float(np.linalg.norm(off))))))
        return az, el

    def update(self, reference: bool = False) -> None:
        """Re-render the splats (and the reference and difference when ``reference``)."""
        level = 0
        if self.chooser is not None:
            level = self.chooser.choose(self.camera)
            self.drawn = self.levels.cloud_at(level)  # sampled once, on the first view that needs it
        self.level = level
        t0 = time.perf_counter()
        try:
            self.frame = renderer_for(self.drawn).render(self.camera, **self.options)
        except GeometryError as exc:  # e.g. zoomed into the solid with every tile splatted: say so, keep the image
            self.label.value = f"not drawn: {html.escape(str(exc))}"
            return
        self.frame_ms = 1e3 * (time.perf_counter() - t0)
        if self.chooser is not None:
            self.chooser.record(level, max(self.frame.stats.ms, 1e-3))
        self.image.value = self.frame.png_bytes(fmt="jpeg")
        stats = self.frame.stats
        text = f"splats: {self.frame_ms:.1f} ms per frame ({len(self.drawn):,} splats of radius {self.drawn.radius:.3g}"
        if self.levels is not None:
            text += f", level of detail {level}" if level else ", the cloud itself"
            if len(self.chooser.candidates) > 1:
                text += " (the faster of levels " + " and ".join(map(str, self.chooser.candidates)) + ", measured)"
        text += f"; {stats.covered} pixels, overdraw {stats.overdraw:.1f}"
        if stats.raytraced_tiles:
            text += f", {stats.raytraced_tiles} of {stats.tiles} tiles ray traced: cheaper there"
        text += ")"
        if self.reference_shape is not None and reference:
            ref = raytrace(self.reference_shape, self.camera, color_by=self.options.get("color_by", "quadric"))
            self.reference_image.value = ref.png_bytes(fmt="jpeg")
            agreement = compare(self.frame, ref)
            self.difference_image.value = self.frame.png_bytes(agreement.picture())
            self._last_reference = (ref.stats.ms, agreement)
        if self.reference_shape is not None and hasattr(self, "_last_reference"):
            ms, agreement = self._last_reference
            stale = "" if reference else " (reference updates when the drag ends)"
            text += (f" · ray tracing: {ms:.0f} ms · agree {agreement.fraction:.4%}, holes {agreement.holes}"
                     f"{stale}")
        self.label.value = text

    # -- interaction -----------------------------------------------------------------------------
    @property
    def zoom_factor(self) -> float:
        """The zoom the zoom slider sets: ``2 ** (viewer.zoom.value / ZOOM_STEPS)`` (1: the initial view)."""
        return 2.0 ** (self.zoom.value / ZOOM_STEPS)

    def _show_zoom(self) -> None:
        self.zoom_readout.value = f"x{self.zoom_factor:.2f}"

    def _show_angles(self) -> None:
        """Set the angle sliders to the camera's angles in whole degrees (``_whole``), rendering nothing."""
        az, el = self._angles()
        self._syncing = True
        try:
            self.azimuth.value, self.elevation.value = _whole(self.azimuth, az), _whole(self.elevation, el)
        finally:
            self._syncing = False

    def _set_camera(self, camera: Camera, reference: bool) -> None:
        self.camera = camera
        self._show_angles()
        self.update(reference=reference)

    def _on_slider(self, change) -> None:
        if self._syncing:
            return
        self._show_zoom()
        zoom = self.zoom_factor
        cam = Camera.orbit(self._base.target, float(self.azimuth.value), float(self.elevation.value),
                           self._base.distance / zoom, self._base.width, self._base.height,
                           up=self._base.up, fov=self._base.fov, projection=self._base.projection,
                           ortho_height=self._base.ortho_height / zoom)
        self.camera = cam
        self.update(reference=True)

    def _on_event(self, event: dict) -> None:
        kind = event.get("type")
        if kind == "mousedown":
            self._drag = (event.get("clientX", 0), event.get("clientY", 0))
        elif kind == "mousemove" and self._drag is not None:
            x, y = event.get("clientX", 0), event.get("clientY", 0)
            dx, dy = x - self._drag[0], y - self._drag[1]
            self._drag = (x, y)
            self._set_camera(self.camera.orbited(-DRAG_DEGREES * dx, DRAG_DEGREES * dy), reference=False)
        elif kind in ("mouseup", "mouseleave") and self._drag is not None:
            self._drag = None
            self.update(reference=True)
        elif kind == "wheel":
            # Through the zoom slider, so that it shows the zoom the wheel sets (its observer re-renders); the
            # slider's range bounds the wheel's too.
            steps = WHEEL_STEPS if event.get("deltaY", 0) < 0 else -WHEEL_STEPS
            self.zoom.value = _whole(self.zoom, self.zoom.value + steps)

    def drag(self, dx: float, dy: float) -> Frame:
        """Orbit as a mouse drag by (dx, dy) pixels would (for scripts and tests); return the frame."""
        self._on_event({"type": "mousedown", "clientX": 0, "clientY": 0})
        self._on_event({"type": "mousemove", "clientX": dx, "clientY": dy})
        self._on_event({"type": "mouseup", "clientX": dx, "clientY": dy})
        return self.frame

    def _ipython_display_(self) -> None:
        from IPython.display import display

        display(self.widget)
