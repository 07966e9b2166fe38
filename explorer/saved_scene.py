"""Scenes without a live explorer: the page ``hkpd-explore --export-html`` writes, and
``hkpd.explorer.show(posterior)`` for notebooks.

Both build the explorer's own scene (the same :class:`~hkpd.explorer.app.ExplorerApp`, its
scene and colouring) on a server bound to a free port of this machine that no browser is sent
to, wait for the first complete view, frame it for a page without the control panel, serialise
it (:mod:`hkpd.explorer.html_page`) and close the server.
"""

from __future__ import annotations

import contextlib
import io
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import rich  # viser's printing library (installed with viser)
import rich.console

from hkpd.explorer.app import ASSUMED_ASPECT, ExplorerApp, framing
from hkpd.explorer.body_settings import NOTHING_STATED, BodyStatement
from hkpd.explorer.framing import body_reach
from hkpd.explorer.html_page import iframe_html, write_page
from hkpd.explorer.provider import Box, PosteriorProvider, PredictionResult
from hkpd.explorer.scene_file import SceneFile
from hkpd.prediction.posterior import BodyPosterior

PAGE_TIMEOUT_S = 300.0
"""Longest wait for the prediction and the first view (a slow CPU under load)."""


class FixedPosterior:
    """A provider that answers every request with one posterior (for :func:`show`: the
    posterior already says what the photo and its occluders gave)."""

    def __init__(self, posterior: BodyPosterior) -> None:
        self.posterior = posterior
        network_input = getattr(posterior, "network_input", None)
        self.proxy = None if network_input is None else network_input.proxy.cpu()

    def predict(
        self,
        image: np.ndarray,
        occluders: Sequence[Box],
        evidence: bool = True,
        bbox: Box | None = None,
    ) -> PredictionResult:
        return PredictionResult(posterior=self.posterior, proxy=self.proxy)


@dataclass(frozen=True)
class ScenePage:
    """One saved scene: a self-contained HTML document that Jupyter shows inline.

    Attributes:
        html: the page (opens from a file, with no server and no network).
        caption: its caption as plain text.
        height: CSS pixels of the inline view in a notebook.
    """

    html: str
    caption: str
    height: int = 520

    def _repr_html_(self) -> str:
        return iframe_html(self.html, self.height)

    def __repr__(self) -> str:
        """A short line (the page itself is megabytes: never the default dataclass repr)."""
        text = f"ScenePage({len(self.html) / 1e6:.1f} MB: {self.caption})"
        return text if len(text) <= 200 else text[:198] + "…)"

    def save(self, path: str | Path, force: bool = False) -> Path:
        """Write the page to ``path``; an existing file is kept unless ``force``."""
        return write_page(path, self.html, force=force)


def render_scene_page(
    provider: PosteriorProvider,
    image: np.ndarray,
    *,
    occluders: Sequence[Box] = (),
    evidence: bool = True,
    silhouette: bool = False,
    person_box: Box | None = None,
    photo_name: str = "the photo",
    model_name: str = "the model",
    num_samples: int = 100,
    num_displayed: int = 10,
    scene: SceneFile | None = None,
    scene_source: str = "",
    stated: BodyStatement = NOTHING_STATED,
) -> ScenePage:
    """The explorer's first view of ``image`` ``(H, W, 3)`` uint8 RGB with ``occluders``
    (photo pixels) hidden, as a :class:`ScenePage` (``silhouette``: with ``evidence``, the
    person mask fitted too, for a provider that can). Given a ``scene`` (its photo is
    ``image``), every setting comes from it instead, the page embeds it and, with
    ``scene_source``, names the file it came from. ``stated``: what is known of the person's
    body (sex, measurements; for a provider that takes it): the caption says it with the drawn
    body's sex and measurements.

    Raises:
        ValueError: an occluder is off the photo.
        RuntimeError: no person was found (pass ``person_box``) or the prediction failed.
    """
    if scene is not None:
        occluders, person_box, evidence = scene.active_boxes, scene.person_box, scene.evidence
        silhouette, num_samples = scene.person_mask, scene.display.num_samples
        num_displayed = scene.display.num_displayed
    with _quiet_server():  # viser prints an address banner nobody is meant to open
        app = ExplorerApp(
            provider, image, host="127.0.0.1", port=0, num_samples=num_samples,
            num_displayed=num_displayed, person_box=person_box, occluders=occluders,
            evidence=evidence, silhouette=silhouette, photo_name=photo_name,
            model_name=model_name, stated=stated,
        )  # fmt: skip
    try:
        if scene is not None:
            app.keeper.photo, app.keeper.model = scene.photo, scene.model
            app.keeper.apply(scene)
            app.keeper.source = scene_source
        if not app.wait_idle(PAGE_TIMEOUT_S):
            raise RuntimeError(f"the prediction took longer than {PAGE_TIMEOUT_S:.0f} s")
        if app.result is None or app.view is None:
            problems = "; ".join(app.errors) or "no person was found: give the person's box"
            raise RuntimeError(f"nothing to show for {photo_name}: {problems}")
        if app.scene.placement is not None:  # a page has no control panel to leave room for
            position, look_at = framing(
                app.scene.placement, ASSUMED_ASPECT, 1.0, app.scene.combined_shown,
                app.compare_columns.shown, body_reach(app.result), app.scene.layout,
            )  # fmt: skip
            app.server.initial_camera.position = position
            app.server.initial_camera.look_at = look_at
        caption = app.page_caption()
        assert caption is not None
        return ScenePage(app.page_html(), caption.text())
    finally:
        with _quiet_server():
            app.stop()


@contextlib.contextmanager
def _quiet_server() -> Iterator[None]:
    """Swallow what viser prints while the private server starts or stops: its address banner
    and "(viser) Server stopped" go through rich's global console, which in a notebook writes
    to the cell's outputs (not to ``sys.stdout``), so that console is swapped for one writing
    nowhere, and ``sys.stdout`` too. (``stop`` joins the server's thread, so its last line
    comes inside.)"""
    sink = io.StringIO()
    saved = rich.get_console()
    rich._console = rich.console.Console(file=sink)  # rich's one global console
    try:
        with contextlib.redirect_stdout(sink):
            yield
    finally:
        rich._console = saved


def show(
    posterior: BodyPosterior,
    image: np.ndarray | None = None,
    *,
    photo_name: str = "the photo",
    model_name: str = "the model that made this posterior",
    num_samples: int = 100,
    num_displayed: int = 10,
    height: int = 520,
) -> ScenePage:
    """The explorer's scene of ``posterior``, for a notebook: the returned page shows inline
    (``_repr_html_``) and can be saved (``.save(path)``).

    Args:
        posterior: a prediction, e.g. ``Predictor.predict(photo, occluders=[box])``.
        image: ``(H, W, 3)`` uint8 RGB photo to draw; default the photo the posterior was
            predicted from, occluders painted (``posterior.network_input.image``).
        height: CSS pixels of the inline view.
    """
    network_input = getattr(posterior, "network_input", None)
    if image is None:
        if network_input is None:
            raise ValueError("this posterior carries no photo: pass image=(H, W, 3) uint8 RGB")
        image = network_input.image.pixels
    boxes = () if network_input is None else tuple(map(tuple, network_input.occluders.boxes))
    page = render_scene_page(
        FixedPosterior(posterior), np.ascontiguousarray(image), occluders=boxes,
        evidence=posterior.conditioned, photo_name=photo_name, model_name=model_name,
        num_samples=num_samples, num_displayed=num_displayed,
    )  # fmt: skip
    return ScenePage(page.html, page.caption, height)
