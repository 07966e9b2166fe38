"""``ExplorerApp``: wires the state, the worker, the scene and the panel around a viser server.

Threads: viser runs callbacks on its thread pool; they only change :class:`ExplorerState` and
submit jobs. The single :class:`CoalescingWorker` runs predictions (lane ``"predict"``,
debounced), new photos (``"image"``), sampling (``"sample"``), further photos of the same person
(``"same_person"``: their uploads queue up, one job predicts them all and shows the combined
shape), exports (``"export"``) and the search for the photo's people (``"people"``, after the
first view), and pushes the results to the global scene, which viser
broadcasts to every tab.
"""

from __future__ import annotations

import functools
import math
import sys
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import cast

import numpy as np
import viser

from hkpd.distributions import MatrixFisher
from hkpd.explorer.app_body import BodyAppActions
from hkpd.explorer.app_keeping import KeepingActions
from hkpd.explorer.app_marks import PhotoMarksActions
from hkpd.explorer.app_turning import TurnAppActions
from hkpd.explorer.body_settings import NOTHING_STATED, BodyStatement
from hkpd.explorer.canvas_key import CanvasKey
from hkpd.explorer.caption_numbers import numbers_sentence
from hkpd.explorer.change_baseline import BaselineCache, BaselineKey
from hkpd.explorer.colour_map import HeatmapScale
from hkpd.explorer.compare import Comparison
from hkpd.explorer.compare_scene import CompareColumns
from hkpd.explorer.export import meshes_file
from hkpd.explorer.framing import (
    ASSUMED_ASPECT,
    CAMERA_FOV_DEG,
    FREE_CANVAS_FRACTION,
    PANEL_WIDTH_PX,
    body_reach,
    framing,
    page_camera,
)
from hkpd.explorer.html_page import SceneCaption, describe_scene, scene_page
from hkpd.explorer.layout import ColumnLayout, column_layout
from hkpd.explorer.notices import NOTICES
from hkpd.explorer.panels import build_panels
from hkpd.explorer.panels.same_person import ONLY_CURRENT_PHOTO
from hkpd.explorer.panels.samples import DEFAULT_FIT_OPACITY
from hkpd.explorer.people_menu import menu_entries, no_person_advice, person_to_show
from hkpd.explorer.photo_geometry import (
    PhotoPlacement,
    quaternion_to_matrix,
    screen_rect_to_box,
)
from hkpd.explorer.posterior_view import PosteriorView, compute_view
from hkpd.explorer.progress import PREDICT, SAMPLE, SEND, Progress
from hkpd.explorer.provider import (
    Box,
    MaskFittingProvider,
    PosteriorProvider,
    PredictionResult,
)
from hkpd.explorer.same_person_shapes import combined_photos
from hkpd.explorer.scene import PHOTO_GAP, ExplorerScene
from hkpd.explorer.scene_file import PhotoRef
from hkpd.explorer.scene_keeping import SceneKeeper
from hkpd.explorer.state import MAX_OCCLUDERS, MAX_SAME_PERSON_PHOTOS, ExplorerState, StateSnapshot
from hkpd.explorer.still_image import captioned_png
from hkpd.explorer.upload import UploadError, decode_upload
from hkpd.explorer.worker import CoalescingWorker
from hkpd.kinematic_tree import body_joint_index
from hkpd.prediction.detection.keypoint_detector import NoPersonFoundError
from hkpd.prediction.exports.fit_overlay import FitOverlay, render_fit_overlay
from hkpd.prediction.posterior import BodyPosterior
from hkpd.prediction.shape_combination import CombinedShape

PREDICTION_DEBOUNCE_S = 0.12
"""Occluder edits closer together than this are coalesced (an isolated edit predicts at once)."""

PEOPLE_SEARCH_DELAY_S = 0.3
"""The person search for the menu waits this long after a new photo's first view, so that the
view reaches the browsers before the search takes the CPU."""

PLAIN_PHOTO_HEIGHT_M = 2.0
"""Height of a photo drawn before any person was found in it (a person-sized photo)."""
WEAK_EVIDENCE_KEYPOINTS = 6
"""Fewer keypoints of evidence than this in a person box: :func:`weak_keypoints_warning`."""
SCREENSHOT_SIZE = (720, 1280)
"""``(height, width)`` of the screenshot requested from the browser."""


@dataclass
class Timings:
    """Seconds the last jobs took (server side), for the status line and the benchmark."""

    predict: float = 0.0
    sample: float = 0.0
    draw: float = 0.0
    compare: float = 0.0
    """B's sampling and drawing after A's (0 without a comparison)."""


class ExplorerApp(KeepingActions, BodyAppActions, TurnAppActions, PhotoMarksActions):
    """The running explorer (its scene and compare actions: :mod:`hkpd.explorer.app_keeping`;
    its Body section's: :mod:`hkpd.explorer.app_body`).

    Args:
        provider: turns a photo and occluders into a posterior (see :mod:`provider`).
        image: ``(H, W, 3)`` uint8 RGB, the first photo.
        host: interface to bind (``127.0.0.1`` keeps it on this machine).
        port: TCP port; 0 picks a free one.
        num_samples: samples for the heatmap (default 100).
        num_displayed: sample meshes drawn (default 10).
        person_box: ``(x0, y0, x1, y1)``: look for the person only there in the first photo.
        occluders: boxes ``(x0, y0, x1, y1)`` (photo pixels) hidden in the first prediction.
        evidence: condition the first prediction on the photo's keypoints (else the network).
        silhouette: with ``evidence``, fit the person mask too (the *Fit the person mask*
            switch; only for a provider that can, :class:`MaskFittingProvider`: ignored
            otherwise).
        photo_name, model_name: what the photo and the model are called in saved pages'
            captions (an uploaded photo goes by its file name).
        stated: what is known of the first photo's person (sex, measurements), for a provider
            that takes it (:class:`~hkpd.explorer.provider.BodyStatingProvider`).

    Raises:
        ValueError: an occluder lies off the photo or is smaller than 2 pixels.
    """

    def __init__(
        self,
        provider: PosteriorProvider,
        image: np.ndarray,
        *,
        host: str = "127.0.0.1",
        port: int = 8080,
        num_samples: int = 100,
        num_displayed: int = 10,
        person_box: tuple[float, float, float, float] | None = None,
        occluders: Sequence[Box] = (),
        evidence: bool = True,
        silhouette: bool = False,
        photo_name: str = "the photo",
        model_name: str = "the model",
        stated: BodyStatement = NOTHING_STATED,
    ) -> None:
        image = _check_image(image)
        self.provider = provider
        self.state = ExplorerState()
        self.state.set_num_samples(num_samples)
        self.state.set_num_displayed(num_displayed)
        self.timings = Timings()
        self.errors: list[str] = []
        self.last_screenshot: np.ndarray | None = None
        self._lock = threading.RLock()
        self._menu_lock = threading.RLock()
        """Held while the Person menu is worked out from the state and set, so that the menu a
        thread sets is never older than one another thread set after a newer person box."""
        self._image = image
        self._image_token = 0
        self._placed_token = -1
        self._result: PredictionResult | None = None
        self._result_key: BaselineKey | None = None
        self.baselines = BaselineCache()
        self._view: PosteriorView | None = None
        self._framed: PhotoPlacement | None = None
        self._same_person_queue: list[tuple[np.ndarray, str, viser.ClientHandle | None, int]] = []
        self._combined: CombinedShape | None = None
        self._people: tuple[Box, ...] = ()
        self._people_token = -1
        self._photo_is_plain = False
        self._photo_name, self.model_name = photo_name, model_name
        lanes = ("image", "predict", "sample", "same_person", "export", "people")
        self.worker = CoalescingWorker(lanes, self._job_failed)
        self.server = viser.ViserServer(host=host, port=port, label="hkpd explorer", verbose=False)
        self.server.initial_camera.fov = math.radians(CAMERA_FOV_DEG)
        self.scene = ExplorerScene(self.server)
        self.key = CanvasKey(self.server)  # what the drawings mean, under the photo
        self.compare = Comparison(self._compare_predict)
        self.compare_columns = CompareColumns(self.server)
        self.keeper = SceneKeeper(self)
        self.panels = build_panels(self.server, self)
        self.panels.photo.silhouette.visible = self.fits_person_mask
        self.progress = Progress(self.server, self.panels.status, self.worker)
        self.server.scene.on_rect_select(modifier="shift")(self._on_rect_select)
        self.server.on_client_connect(lambda client: self._frame_client(client, wait_s=5.0))
        self._plain_drag = False
        self._pick_person = False
        self._overlay: FitOverlay | None = None
        self._fit_visible, self._fit_opacity = True, DEFAULT_FIT_OPACITY
        self.state.set_image(image.shape[1], image.shape[0], person_box)
        self.state.set_evidence(evidence)
        self.state.set_silhouette(silhouette and self.fits_person_mask)
        self.panels.photo.evidence.value = self.state.evidence
        self.panels.photo.silhouette.value = self.state.silhouette
        self.panels.photo.silhouette.disabled = not self.state.evidence
        self.state.set_stated(stated)
        self._show_body(None)
        for box in occluders:
            if self.state.add_occluder(box) is None:
                self.server.stop()
                raise ValueError(f"occluder {tuple(box)} is off the photo or under 2 pixels")
        self.panels.photo.occluders.show(self.state.snapshot().occluders, self.state.image_size)
        # The photo first, at a provisional size: the first prediction places it by the body.
        provisional = provisional_placement(image.shape[1], image.shape[0])
        self.scene.place_photo(image, provisional)
        self._frame_camera(provisional)
        self.worker.start()
        self.worker.submit("predict", self._predict_job)

    # ------------------------------------------------------------------ public API
    @property
    def url(self) -> str:
        """Address to open in a browser on this machine."""
        host = self.server.get_host()
        if host in ("0.0.0.0", "::", ""):
            host = "127.0.0.1"
        elif ":" in host:
            host = f"[{host}]"
        return f"http://{host}:{self.server.get_port()}"

    @property
    def view(self) -> PosteriorView | None:
        """The last displayed posterior view."""
        with self._lock:
            return self._view

    @property
    def result(self) -> PredictionResult | None:
        """The last prediction."""
        with self._lock:
            return self._result

    @property
    def combined_shape(self) -> CombinedShape | None:
        """The shape combined from the current photo and the added photos of the same person
        (None until a photo is added)."""
        with self._lock:
            return self._combined

    def page_caption(self) -> SceneCaption | None:
        """What a saved page of the current scene shows, in words (None before a prediction)."""
        result = self.result
        if result is None:
            return None
        snapshot = self.state.snapshot()
        with self._lock:
            photo, view = self._photo_name, self._view
        setting, view_b = self.compare.setting, self.compare.view
        caption = describe_scene(
            result.posterior,
            photo=photo,
            model=self.model_name,
            occluders=snapshot.active_boxes,
            num_samples=snapshot.num_samples,
            num_displayed=snapshot.num_displayed if self.scene.show_samples else 0,
            concentration_factors=snapshot.concentration_factors,
            numbers="" if view is None else numbers_sentence(view, view_b),
            colouring=self.scene.heatmap.kind,
            compare="" if setting is None or view_b is None else setting.label,
        )
        return replace(caption, scene_source=self.keeper.source)

    def page_html(self) -> str:
        """The current scene as one self-contained HTML page with its caption and the scene
        file it shows embedded (:mod:`hkpd.explorer.html_page`); nothing of the live app
        (its hints, its buttons) is in it."""
        caption = self.page_caption()
        if caption is None:
            raise RuntimeError("nothing to save yet: the first prediction has not finished")
        scene = None if self.keeper.photo is None else self.keeper.scene().to_json()
        with self.scene.static_titles(), page_camera(self.server.initial_camera, **self._row()):
            return scene_page(self.server, caption, scene)

    def wait_idle(self, timeout: float = 30.0) -> bool:
        """Block until no work is pending (for tests and benchmarks)."""
        return self.worker.wait_idle(timeout)

    def stop(self) -> None:
        """Stop the worker and the server."""
        self.worker.stop()
        self.server.stop()

    def add_occluder(self, box: tuple[float, float, float, float]) -> bool:
        """Add an occluder in photo pixels (what a drag on the photo does)."""
        return self.occluders_changed(self.state.add_occluder(box) is not None)

    def clear_occluders(self) -> None:
        self.occluders_changed(self.state.clear_occluders())

    def show_fit(self, visible: bool, opacity: float) -> None:
        """Show (or hide) the mode mesh over the photo at ``opacity``."""
        with self._lock:
            self._fit_visible, self._fit_opacity = bool(visible), float(opacity)
            overlay = self._overlay
        if overlay is None or not visible:
            self.scene.show_fit_overlay(None, None)
        else:
            self.scene.show_fit_overlay(overlay.with_opacity(opacity), overlay.box)

    def set_evidence(self, enabled: bool) -> None:
        """Condition on the photo's 2D keypoints, or show the network alone (predicts again)."""
        if self.state.set_evidence(enabled):
            self.panels.photo.silhouette.disabled = not enabled
            self.worker.submit("predict", self._predict_job)

    @property
    def fits_person_mask(self) -> bool:
        """The provider can fit the person mask (:class:`MaskFittingProvider`)."""
        return bool(getattr(self.provider, "fits_person_mask", False))

    def set_silhouette(self, enabled: bool) -> None:
        """Fit the person mask as well as the keypoints, or the keypoints alone (predicts
        again; only for a provider that can, :attr:`fits_person_mask`)."""
        if self.fits_person_mask and self.state.set_silhouette(enabled):
            self.worker.submit("predict", self._predict_job)

    def _provider_predict(
        self,
        image: np.ndarray,
        boxes: Sequence[Box],
        evidence: bool,
        silhouette: bool,
        bbox: Box | None = None,
        stated: BodyStatement | None = None,
    ) -> PredictionResult:
        """The provider's prediction; the person mask is asked for only with ``evidence`` and
        ``silhouette`` both on, so providers that cannot fit it work as before, and the
        ``stated`` body (None: the state's) only with ``evidence``, from providers that take
        it."""
        body = self._body_arguments(stated, evidence)
        if evidence and silhouette and self.fits_person_mask:
            provider = cast(MaskFittingProvider, self.provider)
            return provider.predict(image, boxes, True, bbox, silhouette=True, **body)
        return self.provider.predict(image, boxes, evidence=evidence, bbox=bbox, **body)

    def set_person_box(self, box: tuple[float, float, float, float] | None) -> bool:
        """Look for the person only inside ``box`` (None: anywhere); predicts again."""
        changed = self.state.set_person_box(box)
        if changed:
            self.scene.show_person_box(self.state.snapshot().person_box)
            self._show_person_menu()
            self.worker.submit("predict", self._predict_job)
        return changed

    def _show_person_menu(self) -> None:
        """The Person menu for the photo's people, naming whom the person box holds: one of
        them, or a box the user picked ("Your box")."""
        with self._menu_lock:
            result, box = self.result, self.state.snapshot().person_box
            reading = getattr(result and result.posterior, "person_box", None)
            choice, places = menu_entries(self.people, box, reading, self.state.image_size)
            self.panels.photo.show_people(len(places), choice, places)
            self.scene.people_marks.show(self.people)  # numbered on the photo

    @property
    def people(self) -> tuple[Box, ...]:
        """The boxes of every person found in the current photo (empty when the provider cannot
        list them, or found nobody)."""
        with self._lock:
            return self._people

    def select_person(self, index: int) -> bool:
        """Predict for person ``index`` of :attr:`people`; False when there is no such person."""
        people = self.people
        if not 0 <= index < len(people):
            return False
        return self.set_person_box(people[index])

    def pick_person_next(self, enabled: bool = True) -> None:
        """The next box dragged on the photo picks the person instead of adding an occluder
        (the status line says so)."""
        with self._lock:
            self._pick_person = enabled
        if enabled:
            self.panels.status.show_picking()

    def set_plain_drag_draws(self, enabled: bool) -> None:
        """Also draw occluders with a plain left drag (the camera then stops orbiting)."""
        with self._lock:
            if enabled and not self._plain_drag:
                self.server.scene.on_rect_select(modifier=None)(self._on_rect_select_plain)
            elif not enabled and self._plain_drag:
                self.server.scene.remove_rect_select_callback(self._on_rect_select_plain)
            self._plain_drag = enabled

    # ------------------------------------------------------------------ change notifications
    def occluders_changed(self, changed: bool) -> bool:
        """Redraw the boxes now; predict again once the edits pause."""
        if changed:
            snapshot = self.state.snapshot()
            self.scene.show_occluders(snapshot.occluders)
            self.panels.photo.occluders.show(snapshot.occluders, snapshot.image_size)
            self.worker.submit("predict", self._predict_job, PREDICTION_DEBOUNCE_S, leading=True)
        return changed

    def sampling_changed(self, changed: bool) -> None:
        """Draw new samples (coalesced: only the newest request runs)."""
        if changed:
            self.worker.submit("sample", self._sample_job)

    def redraw(self) -> None:
        """Redraw after a display option changed (a sampling job: it must not replace one)."""
        self.worker.submit("sample", self._sample_job)

    def set_display_options(
        self,
        samples: bool,
        heatmap: bool,
        reprojection: bool,
        heatmap_max_cm: float,
        colouring: str = "log",
    ) -> bool:
        """Which parts are drawn, the uncertainty body's colouring (a key of
        :data:`~hkpd.explorer.colour_map.COLOURINGS`) and the linear scale's top; True if the
        colour scale changed."""
        scene = self.scene
        scene.show_samples, scene.show_heatmap = bool(samples), bool(heatmap)
        scene.show_reprojection = bool(reprojection)
        scale = HeatmapScale(colouring, float(heatmap_max_cm))
        rescaled = scene.heatmap != scale
        if rescaled:
            scene.heatmap = scale
            if scene.legend_scale is not None:  # a body is drawn: its colour bar follows
                scene.show_legend()
            self.key.show(colouring=scale.kind)
            if scene.placement is not None:  # the column titles follow the colouring
                scene.show_titles(scene.titles_top)
            if scene.combined_shown:  # recolour the combined shape (and its colour bar)
                self.worker.submit("same_person", self._same_person_job)
        self.redraw()
        return rescaled

    def load_upload(self, name: str, content: bytes, client: viser.ClientHandle | None) -> None:
        """Check an uploaded photo now; predict on it in the worker. Errors notify ``client``."""
        try:
            image = decode_upload(name, content)
        except UploadError as error:
            self._notify(client, "Photo not loaded", str(error), error=True)
            return
        photo = PhotoRef.of_bytes(content, name)
        self.worker.submit("image", lambda: self._image_job(image, name, client, photo))

    def add_same_person_upload(
        self, name: str, content: bytes, client: viser.ClientHandle | None
    ) -> None:
        """Check an uploaded further photo of the current person now; predict its shape and
        show the combined shape in the worker. Errors notify ``client``."""
        try:
            image = decode_upload(name, content)
        except UploadError as error:
            self._notify(client, "Photo not added", str(error), error=True)
            return
        self.add_same_person_photo(image, name, client)

    def add_same_person_photo(
        self, image: np.ndarray, name: str, client: viser.ClientHandle | None = None
    ) -> None:
        """Add ``image`` ``(H, W, 3)`` uint8 as one more photo of the current photo's person
        (queued: photos added quickly one after the other are all kept)."""
        image = _check_image(image)
        with self._lock:
            self._same_person_queue.append((image, name, client, self._image_token))
        self.worker.submit("same_person", self._same_person_job)

    def clear_same_person(self) -> None:
        """Forget the added photos of the person (the combined shape disappears)."""
        if self.state.clear_same_person():
            self.worker.submit("same_person", self._same_person_job)

    def request_export(self, file_format: str, client: viser.ClientHandle) -> None:
        self.worker.submit("export", lambda: self._export_job(file_format, client))

    def request_screenshot(self, client: viser.ClientHandle) -> None:
        self.worker.submit("export", lambda: self._screenshot_job(client))

    def request_page(self, client: viser.ClientHandle) -> None:
        self.worker.submit("export", lambda: self._page_job(client))

    # ------------------------------------------------------------------ pointer events
    def _on_rect_select(self, event: viser.SceneRectSelectEvent) -> None:
        placement = self.scene.placement
        if placement is None:
            return
        camera = event.client.camera
        box = screen_rect_to_box(
            event.screen_min,
            event.screen_max,
            camera.position,
            quaternion_to_matrix(camera.wxyz),
            camera.fov,
            camera.aspect,
            placement,
        )
        with self._lock:
            picking, self._pick_person = self._pick_person, False
        if picking:
            if box is None or not self.set_person_box(box):
                self._notify(event.client, "No person box", "Drag a box around the person.")
            return
        if box is None:
            self._notify(
                event.client,
                "No occluder drawn",
                "Drag a box over the photo (at least 2 pixels each way).",
            )
        elif self.state.occluders_full:
            self._notify(
                event.client,
                "No occluder drawn",
                f"At most {MAX_OCCLUDERS} occluders: delete or reuse one first.",
                error=True,
            )
        elif not self.add_occluder(box):
            self._notify(event.client, "No occluder drawn", "The box is too small.")

    def _on_rect_select_plain(self, event: viser.SceneRectSelectEvent) -> None:
        self._on_rect_select(event)

    # ------------------------------------------------------------------ jobs (worker thread)
    def _predict_job(self) -> None:
        snapshot = self.state.snapshot()
        with self._lock:
            image, token = self._image, self._image_token
        started = time.perf_counter()
        self.progress.step(PREDICT)
        try:
            result = self._provider_predict(
                image, snapshot.active_boxes, snapshot.evidence, snapshot.silhouette,
                bbox=snapshot.person_box, stated=snapshot.stated,
            )  # fmt: skip
        except NoPersonFoundError:
            self._no_person(image, token)
            return
        self._remember_reading(token, snapshot, result)  # for Turn around (app_turning)
        self._show_reading(self._turned(result), image, token, snapshot, started)

    def _show_reading(
        self,
        result: PredictionResult,
        image: np.ndarray,
        token: int,
        snapshot: StateSnapshot,
        started: float,
    ) -> None:
        """Show the person's ``result``, predicted from ``snapshot`` by a job begun at
        ``started`` (``time.perf_counter()``)."""
        self.timings.predict = time.perf_counter() - started
        key = _baseline_key(token, snapshot.person_box, snapshot)
        self._show_prediction(result, image, token, key, not snapshot.active_boxes)

    def _find_people(self, image: np.ndarray, token: int) -> None:
        """List the photo's people (when the provider can) and offer them in the panel."""
        finder = getattr(self.provider, "find_people", None)
        people: tuple[Box, ...] = ()
        if finder is not None:
            try:
                people = tuple(tuple(float(v) for v in box) for box in finder(image))
            except Exception as error:  # listing people is a convenience: say so, go on
                self.errors.append(f"listing the people failed: {error}")
        with self._lock:
            if token != self._image_token:
                return
            self._people, self._people_token = people, token
            result = self._result
        self._show_person_menu()
        if self.state.snapshot().person_box is None and result is not None:
            reading = getattr(result.posterior, "person_box", None)  # read as --all-people does:
            shown = person_to_show(people, reading, self.state.image_size)  # in the listed box
            if shown is not None:
                self.select_person(shown)

    def _no_person(
        self, image: np.ndarray, token: int, client: viser.ClientHandle | None = None
    ) -> None:
        """Nobody found on photo ``token``: clear the last person's body, draw the photo (so that
        a box can be dragged on it) and tell every tab (or ``client``) how to pick the person."""
        with self._lock:
            if token != self._image_token:
                return  # a newer photo replaced this one meanwhile
            self._result, self._view, self._overlay = None, None, None
            new_photo = token != self._placed_token
            self._placed_token = token
            self._photo_is_plain = self._photo_is_plain or new_photo
        self.scene.clear_bodies()
        self.compare.clear()
        self.compare_columns.clear()
        self.panels.compare.numbers.content = ""
        self.panels.teaching.axes_text.content = ""  # the last person's concentrations
        if new_photo:
            self._place_photo(image, plain_placement(image.shape[1], image.shape[0]), token)
        self.scene.show_occluders(self.state.snapshot().occluders)
        self.scene.show_person_box(self.state.snapshot().person_box)
        self.panels.status.source.content = ""
        self._show_marks(None)
        self._show_body(None)
        self._show_turn(None)
        advice = no_person_advice(self.state.snapshot().person_box)
        self.panels.status.show_status(f"**{advice}**")
        clients = [client] if client is not None else self.server.get_clients().values()
        for each in clients:
            self._notify(each, "No person found", advice.replace("**", ""), error=True)

    def _place_photo(
        self, image: np.ndarray, placement: PhotoPlacement, token: int,
        layout: ColumnLayout | None = None,
    ) -> None:  # fmt: skip
        """Draw photo ``token`` at ``placement`` (the columns at ``layout``; None: where they
        are) and frame it; its people are listed once, in the ``"people"`` lane after
        :data:`PEOPLE_SEARCH_DELAY_S` (after the first view is sent: the person search reads
        the photo 10 times)."""
        if layout is not None:
            self.scene.set_layout(layout)
            self.compare_columns.set_layout(layout)
        self.scene.place_photo(image, placement)
        self.key.show(placement, self.scene.heatmap.kind)
        self.scene.show_titles(max(placement.centre[1] + placement.height_m / 2, 1.0) + 0.08)
        self._frame_camera(placement)
        if token != self._people_token:
            people_job = lambda: self._find_people(image, token)  # noqa: E731
            self.worker.submit("people", people_job, delay_s=PEOPLE_SEARCH_DELAY_S)

    def _image_job(
        self,
        image: np.ndarray,
        name: str,
        client: viser.ClientHandle | None,
        photo: PhotoRef | None = None,
    ) -> None:
        started = time.perf_counter()
        self.progress.step(PREDICT)
        snapshot = self.state.snapshot()
        result: PredictionResult | None = None
        try:
            result = self._provider_predict(  # a new person: nothing stated yet
                image, [], snapshot.evidence, snapshot.silhouette, stated=NOTHING_STATED
            )
        except NoPersonFoundError:
            pass  # the photo is shown all the same: the user picks the person on it
        except Exception as error:  # the predictor's own message says what is wrong
            self._notify(client, "Photo not loaded", f"{name}: {error}", error=True)
            return
        self.timings.predict = time.perf_counter() - started
        with self._lock:
            self._image, self._photo_name = image, name
            self._image_token += 1
            token = self._image_token
            self.state.set_image(image.shape[1], image.shape[0])
        self.keeper.photo, self.keeper.source = photo, ""
        self.keeper.forget_history()
        snapshot = self.state.snapshot()
        self.panels.photo.occluders.show(snapshot.occluders, snapshot.image_size)
        self.scene.show_person_box(None)
        if result is None:
            self._notify(client, "Photo loaded", name)
            self._no_person(image, token, client)
            return
        self._show_prediction(result, image, token, _baseline_key(token, None, snapshot))
        kept = self.keeper.differences()  # concentrations and display settings stay: say so
        if kept:
            self._notify(client, "Settings kept from the last photo", kept)
        self._notify(client, "Photo loaded", name)

    def _show_prediction(
        self,
        result: PredictionResult,
        image: np.ndarray,
        token: int,
        key: BaselineKey,
        without_occluders: bool = True,
    ) -> None:
        """Show ``result`` (predicted for ``key``; the change colouring's baseline when it was
        predicted ``without_occluders``)."""
        with self._lock:
            if token != self._image_token:
                return  # a newer photo replaced this one meanwhile
            self._result, self._result_key = result, key
            new_photo = token != self._placed_token
            self._placed_token = token
            plain, self._photo_is_plain = self._photo_is_plain, False
        if without_occluders:
            self.baselines.record(key, result.posterior)
        posterior = result.posterior
        if new_photo or plain:
            layout = column_layout(result)  # the columns spaced by this person's reach
            placement = photo_placement(result, image.shape[1], image.shape[0], layout.photo_gap)
            self._place_photo(image, placement, token, layout)
            self.scene.show_person_box(self.state.snapshot().person_box)
        self.scene.show_occluders(self.state.snapshot().occluders)
        warning = weak_keypoints_warning(posterior)
        if warning is not None:
            for client in self.server.get_clients().values():
                self._notify(client, "Weak keypoints", warning.replace("**", ""), error=True)
        overlay = _fit_overlay(posterior)
        with self._lock:
            self._overlay = overlay
            visible, opacity = self._fit_visible, self._fit_opacity
        self.show_fit(visible, opacity)
        self.scene.show_keypoints(
            posterior.keypoints.cpu().numpy(), posterior.confidences.cpu().numpy()
        )
        self._show_turn(posterior)
        self._show_marks(posterior)
        self.panels.teaching.show_proxy(result.proxy)
        self.panels.teaching.show_shape_basis(
            posterior, result.proxy, None if overlay is None else overlay.rgba
        )
        self.compare.predict(image, self.state.snapshot(), result)
        self._sample_job()
        self._show_body(posterior)  # after the bodies are drawn: measuring takes ~0.1 s a sex
        if self.state.snapshot().same_person or self.scene.combined_shown:
            self._show_combined()

    def _same_person_job(self) -> None:
        """Predict the queued photos of the same person, keep their shapes, show the result."""
        with self._lock:
            queue, self._same_person_queue = self._same_person_queue, []
        snapshot = self.state.snapshot()
        for image, name, client, token in queue:
            try:
                posterior = self._provider_predict(
                    image, [], snapshot.evidence, snapshot.silhouette, stated=snapshot.stated
                ).posterior
            except NoPersonFoundError:
                self._notify(client, "Photo not added", f"{name}: no person found.", error=True)
                continue
            except Exception as error:  # the predictor's own message says what is wrong
                self._notify(client, "Photo not added", f"{name}: {error}", error=True)
                continue
            mean = tuple(posterior.shape_mean.detach().cpu().double().tolist())
            std = tuple(posterior.shape_std.detach().cpu().double().tolist())
            with self._lock:  # a new photo (a new person) replaces the token and the set
                current = token == self._image_token
                added = current and self.state.add_same_person_shape(
                    name, mean, std, posterior.sexes, posterior.stated
                )
            if not current:
                reason = f"{name}: a new photo was loaded meanwhile; add it for the new person."
                self._notify(client, "Photo not added", reason, error=True)
            elif not added:
                reason = f"At most {MAX_SAME_PERSON_PHOTOS} further photos: forget some first."
                self._notify(client, "Photo not added", reason, error=True)
            else:
                count = len(self.state.snapshot().same_person) + 1
                self._notify(client, "Photo added", f"{name}: {count} photos of this person")
        self._show_combined()

    def _show_combined(self) -> None:
        """Draw (or remove) the shape combined from the current photo and the added ones."""
        with self._lock:
            result = self._result
        added = self.state.snapshot().same_person
        was_shown = self.scene.combined_shown
        if result is None or not added:
            with self._lock:
                self._combined = None
            self.scene.show_combined_shape(None, None)
            self.panels.same_person.show(ONLY_CURRENT_PHOTO)
        else:
            posterior = result.posterior
            current = (posterior.shape_mean.detach().cpu().double(),
                       posterior.shape_std.detach().cpu().double())  # fmt: skip
            combined = combined_photos(posterior, added)
            with self._lock:
                self._combined = combined
            uncertainty = combined.vertex_uncertainty.detach().cpu().numpy()
            title = f"Combined shape · {combined.count} photos"  # std: in the panel
            self.scene.show_combined_shape(
                combined.tpose_vertices.detach().cpu().numpy(), uncertainty, title
            )
            names = ", ".join(s.name for s in added)
            self.panels.same_person.show(
                f"**{combined.count} photos** of this person (the current one + {names}).\n\n"
                f"Mean shape std {combined.mean_std:.3f} (current photo alone "
                f"{float(current[1].mean()):.3f}); T-pose vertex uncertainty "
                f"{float(uncertainty.mean()) * 100:.2f} cm on average."
            )
        with self._lock:
            placement = self._framed
        if placement is not None and was_shown != self.scene.combined_shown:
            self._frame_camera(placement)  # make room for the combined body, or take it back

    def _sample_job(self) -> None:
        with self._lock:
            result = self._result
        if result is None:
            return
        snapshot = self.state.snapshot()
        started = time.perf_counter()
        self.progress.step(SAMPLE)
        view = compute_view(result.posterior, snapshot, self._baseline_uncertainty(snapshot))
        drawn = time.perf_counter()
        self.progress.step(SEND)
        self.scene.show_view(view, faces=result.posterior.body.faces.cpu().numpy())
        done = time.perf_counter()
        self.timings.sample, self.timings.draw = drawn - started, done - drawn
        with self._lock:
            self._view = view
        self._show_compare(snapshot, view)
        index = list(snapshot.concentration_factors)
        joint = body_joint_index(snapshot.selected_joint)
        joint_factor = index[joint]
        prior = None
        network_posterior = result.posterior.prior
        if network_posterior is not None:
            prior = joint_factor * MatrixFisher(network_posterior.F[joint].double()).concentration
        self.panels.teaching.show_teaching(
            view.axes.joint, view.axes.concentrations, joint_factor, prior_concentrations=prior
        )
        self.panels.status.show_source(result.posterior)
        warning = weak_keypoints_warning(result.posterior)
        if warning is not None:
            self.panels.status.source.content += f"\n\n{warning}"
        self.panels.status.show_status(
            f"Prediction {self.timings.predict * 1000:.0f} ms · "
            f"{snapshot.num_samples} samples + heatmap {self.timings.sample * 1000:.0f} ms · "
            f"drawing {self.timings.draw * 1000:.0f} ms"
        )

    def _baseline_uncertainty(self, snapshot: StateSnapshot) -> np.ndarray | None:
        """The change colouring's baseline uncertainty for the shown result while that
        colouring is on (else None: no extra sampling); the baseline posterior is predicted
        here, once per photo and person, when it is missing."""
        with self._lock:
            key, image, token = self._result_key, self._image, self._image_token
        if key is None or key.image_token != token or self.scene.heatmap.kind != "change":
            return None
        predict = functools.partial(self._predict_baseline, image, key)
        if self.baselines.posterior(key, predict) is None:
            return None
        return self.baselines.uncertainty(key, snapshot.num_samples, snapshot.seed)

    def _predict_baseline(self, image: np.ndarray, key: BaselineKey) -> BodyPosterior:
        result = self._provider_predict(
            image, [], key.evidence, key.silhouette, bbox=key.person_box, stated=key.stated
        )
        return self._turned(result, key.turned).posterior

    def _export_job(self, file_format: str, client: viser.ClientHandle) -> None:
        view = self.view
        if view is None:
            return
        data = meshes_file(view.mode_vertices, view.sample_vertices, self.scene.faces, file_format)
        client.send_file_download(f"hkpd_bodies.{file_format}", data, save_immediately=True)

    def _page_job(self, client: viser.ClientHandle) -> None:
        if self.result is None:
            self._notify(client, "No page saved", "Wait for the first prediction.", error=True)
            return
        client.send_file_download(
            "hkpd_scene.html", self.page_html().encode("utf-8"), save_immediately=True
        )

    def _screenshot_job(self, client: viser.ClientHandle) -> None:
        height, width = SCREENSHOT_SIZE
        with self.scene.static_titles():  # a PNG says nothing of the live app
            image = client.get_render(height, width, transport_format="png", timeout=30.0)
        self.last_screenshot = image
        caption = self.page_caption()
        text = "" if caption is None else caption.text(interactive=False)
        png = captioned_png(image, text)  # cropped to the scene, captioned under it
        client.send_file_download("hkpd_explorer.png", png, save_immediately=True)

    def _job_failed(self, lane: str, error: BaseException) -> None:
        message = f"{type(error).__name__}: {error}"
        self.errors.append(f"{lane}: {message}")
        print(f"hkpd-explore: could not {lane}: {message}", file=sys.stderr, flush=True)
        self.panels.status.show_status(f"**Could not {lane}:** {message}")
        for client in self.server.get_clients().values():
            self._notify(client, f"Could not {lane}", message, error=True)

    # ------------------------------------------------------------------ helpers
    def _frame_camera(self, placement: PhotoPlacement) -> None:
        """Frame the photo, the bodies and the heatmap for new tabs and every open tab."""
        with self._lock:
            self._framed = placement
        position, look_at = framing(aspect=ASSUMED_ASPECT, **self._row())
        self.server.initial_camera.position = position
        self.server.initial_camera.look_at = look_at
        for client in self.server.get_clients().values():
            self._frame_client(client)

    def _row(self) -> dict:
        """What :func:`framing` frames: the photo and the columns shown (by the person's reach)."""
        return {"placement": self._framed, "combined": self.scene.combined_shown,
                "compare": self.compare_columns.shown, "reach": body_reach(self.result),
                "layout": self.scene.layout}  # fmt: skip

    def _frame_client(self, client: viser.ClientHandle, wait_s: float = 0.0) -> None:
        """Frame one tab for its own canvas shape (waiting up to ``wait_s`` for it to report)."""
        with self._lock:
            placement = self._framed
        if placement is None:
            return
        deadline = time.monotonic() + wait_s
        aspect, free = None, FREE_CANVAS_FRACTION
        while aspect is None:
            try:
                aspect = client.camera.aspect
                free = 1.0 - PANEL_WIDTH_PX / max(client.camera.image_width, 1)
            except AssertionError:  # the browser has not reported its camera yet
                if time.monotonic() >= deadline:
                    aspect = ASSUMED_ASPECT
                else:
                    time.sleep(0.05)
        free = float(np.clip(free, 0.5, 1.0))
        position, look_at = framing(aspect=aspect, free_fraction=free, **self._row())
        client.camera.position = position
        client.camera.look_at = look_at

    @staticmethod
    def _notify(
        client: viser.ClientHandle | None, title: str, body: str, error: bool = False
    ) -> None:
        if client is not None:  # the tab's last notification of this title goes
            NOTICES.show(client, title, body, error)


def _baseline_key(token: int, person_box: Box | None, snapshot: StateSnapshot) -> BaselineKey:
    """The baseline key of a prediction of photo ``token`` with the snapshot's evidence."""
    return BaselineKey(
        token, person_box, snapshot.evidence, snapshot.evidence and snapshot.silhouette,
        snapshot.stated, snapshot.turned_around,
    )  # fmt: skip


def photo_placement(
    result: PredictionResult, width: int, height: int, gap: float = PHOTO_GAP
) -> PhotoPlacement:
    """Size and place the photo so that the person in it stands as tall as the mode body, its
    right edge ``gap`` metres left of the body's centre.

    The photo's scale is the mode's 3D keypoint height over its 2D keypoint height (clamped to
    keep odd predictions from making a tiny or huge photo); the hips line up with the body's.
    """
    mode = result.posterior.mode()
    points3d = mode.keypoints3d[0].double().cpu().numpy()
    points2d = mode.keypoints2d[0].double().cpu().numpy()
    extent2d = np.ptp(points2d[:, 1])
    metres_per_pixel = np.ptp(points3d[:, 1]) / extent2d if extent2d > 1 else 2.0 / height
    height_m = float(np.clip(height * metres_per_pixel, 1.0, 4.0))
    metres_per_pixel = height_m / height
    hips2d = points2d[11:13].mean(0)
    hips3d = points3d[11:13].mean(0)
    centre_y = -hips3d[1] + (hips2d[1] - height / 2) * metres_per_pixel
    width_m = height_m * width / height
    centre_x = -(gap + width_m / 2)
    return PhotoPlacement(width, height, (centre_x, float(centre_y), 0.0), height_m)


def plain_placement(width: int, height: int) -> PhotoPlacement:
    """Where a photo without a found person goes: :data:`PLAIN_PHOTO_HEIGHT_M` tall, its
    bottom on the floor, left of the bodies (replaced once a person is predicted)."""
    width_m = PLAIN_PHOTO_HEIGHT_M * width / height
    centre = (-(PHOTO_GAP + width_m / 2), PLAIN_PHOTO_HEIGHT_M / 2 - 1.0, 0.0)
    return PhotoPlacement(width, height, centre, PLAIN_PHOTO_HEIGHT_M)


def weak_keypoints_warning(posterior: object) -> str | None:
    """A warning (markdown) when the person box the keypoints were read in may hold no person:
    the person detector found nobody there (the landmark model read the box itself), or fewer
    than :data:`WEAK_EVIDENCE_KEYPOINTS` keypoints are evidence; None otherwise, and for a
    posterior without a detection (a custom provider's)."""
    network_input = getattr(posterior, "network_input", None)
    detection = getattr(network_input, "detection", None)
    if detection is None or detection.search_box is None:
        return None
    shown = int(np.asarray(network_input.evidence).sum())
    confidence = float(np.mean(detection.confidences))
    if detection.detector_score is not None and shown >= WEAK_EVIDENCE_KEYPOINTS:
        return None
    why = (
        "the person detector found nobody in the box"
        if detection.detector_score is None
        else f"only {shown} keypoints are evidence"
    )
    return (
        f"**Weak keypoints:** {why} ({shown} of 17 keypoints confident enough, mean confidence "
        f"{confidence:.2f}); the box may not hold a person."
    )


def provisional_placement(width: int, height: int) -> PhotoPlacement:
    """Where the photo stands before the first prediction: 2 m tall, its bottom on the floor."""
    height_m = 2.0
    width_m = height_m * width / height
    return PhotoPlacement(width, height, (-(PHOTO_GAP + width_m / 2), 0.0, 0.0), height_m)


def _fit_overlay(posterior) -> FitOverlay | None:
    """The mode drawn over the photo, or None for a posterior without a body model or crop
    (a custom provider's)."""
    try:
        return render_fit_overlay(posterior)
    except (AttributeError, TypeError, ValueError):
        return None


def _check_image(image: np.ndarray) -> np.ndarray:
    array = np.asarray(image)
    if array.ndim != 3 or array.shape[2] != 3 or array.dtype != np.uint8:
        raise ValueError(f"the photo must be (H, W, 3) uint8 RGB, got {array.shape} {array.dtype}")
    return np.ascontiguousarray(array)
