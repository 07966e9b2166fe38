"""The app's actions for keeping scenes and comparing settings (the "Scene" and "Compare"
panel sections), as a mixin of :class:`~hkpd.explorer.app.ExplorerApp`, so that the app's own
module keeps only the wiring.

Jobs run in the app's worker like the others: loading a scene with another photo goes through
the ``"image"`` lane (the photo first, then the scene's settings); B is predicted with every
prediction of A and sampled with every view of A (:mod:`hkpd.explorer.compare`).
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

import numpy as np
import viser

from hkpd.explorer.caption_numbers import limb_uncertainty_cm
from hkpd.explorer.compare import CompareSetting
from hkpd.explorer.posterior_view import PosteriorView
from hkpd.explorer.scene_file import SceneFile, SceneFileError, parse_scene
from hkpd.explorer.state import StateSnapshot
from hkpd.explorer.upload import UploadError, decode_upload

if TYPE_CHECKING:
    from hkpd.explorer.app import ExplorerApp

    _Base = ExplorerApp
else:
    _Base = object


class KeepingActions(_Base):
    """Save/Load/Undo/Redo/Reset and Compare, for :class:`ExplorerApp`."""

    # ------------------------------------------------------------------ compare
    def set_compare(self, setting: CompareSetting | None) -> None:
        """Compare against ``setting`` (None: off): B is predicted with the next prediction."""
        try:
            changed = self.compare.set_setting(setting)
        except RuntimeError as error:
            self.compare_failed(str(error), None)
            return
        self.panels.compare.show(setting)
        if changed:
            self.worker.submit("predict", self._predict_job)

    def compare_failed(self, message: str, client: viser.ClientHandle | None) -> None:
        """Say in the Compare folder (and to ``client``) why a setting was refused."""
        self.panels.compare.numbers.content = f"**Not compared:** {message}"
        self._notify(client, "Not compared", message, error=True)

    def _show_compare(self, snapshot: StateSnapshot, view: PosteriorView) -> None:
        """B's view for ``view`` (A's), drawn in B's columns; the scene line and undo history
        follow every view."""
        started = time.perf_counter()
        setting = self.compare.setting
        view_b = None if setting is None else self.compare.compute(snapshot, view)
        was_shown = self.compare_columns.shown
        if view_b is None or setting is None:
            self.compare_columns.clear()
            error = self.compare.error
            self.panels.compare.numbers.content = "" if error is None else f"**B:** {error}"
        else:
            self.compare_columns.show(
                view_b, self.scene.faces, self.scene.heatmap, setting.label, self.scene.titles_top,
                self.scene.show_samples, same_bodies=self.compare.reused,
            )  # fmt: skip
            self.panels.compare.numbers.content = compare_table(view, view_b)
        self.timings.compare = time.perf_counter() - started
        self.scene.set_compared(self.compare_columns.shown)  # A's titles say "A" beside B
        if was_shown != self.compare_columns.shown:
            with self._lock:
                placement = self._framed
            if placement is not None:
                self._frame_camera(placement)
        self.panels.keep.show_changes(self.keeper.differences())
        self.keeper.record()

    # ------------------------------------------------------------------ scenes
    def save_scene(self, client: viser.ClientHandle | None) -> None:
        """Send the current scene (:class:`SceneFile` JSON) to ``client`` as a download."""
        try:
            scene = self.keeper.scene()
        except RuntimeError as error:
            self._notify(client, "No scene saved", str(error), error=True)
            return
        if client is not None:
            content = scene.to_json().encode("utf-8")
            client.send_file_download("hkpd_scene.json", content, save_immediately=True)

    def load_scene_upload(
        self, name: str, content: bytes, client: viser.ClientHandle | None
    ) -> None:
        """Open an uploaded scene file or exported page; errors notify ``client``."""
        try:
            scene = parse_scene(content.decode("utf-8", errors="replace"), name)
        except SceneFileError as error:
            self._notify(client, "Scene not loaded", str(error), error=True)
            return
        self.open_scene(scene, client, source=name)

    def open_scene(
        self, scene: SceneFile, client: viser.ClientHandle | None = None, source: str = ""
    ) -> None:
        """Show ``scene``: its photo (when it is not the current one), then its settings."""
        current = self.keeper.photo
        if current is not None and current.sha256 == scene.photo.sha256:
            self._apply_scene(scene, source, client)
            return
        try:
            content = scene.photo.read()
            image = decode_upload(scene.photo.file_name(content), content)
        except (SceneFileError, UploadError) as error:
            self._notify(client, "Scene not loaded", str(error), error=True)
            return

        def job() -> None:
            self._image_job(image, scene.photo.name, client, scene.photo)
            self._apply_scene(scene, source, client)

        self.worker.submit("image", job)

    def _apply_scene(self, scene: SceneFile, source: str, client) -> None:
        if scene.model != self.keeper.model:
            saved = scene.model or "the shipped model"
            self._notify(client, "Another model", f"The scene was saved with {saved}; this "
                         f"explorer runs {self.model_name}.", error=True)  # fmt: skip
        self.keeper.apply(scene)
        self.keeper.source = source
        self._notify(client, "Scene loaded", source or scene.photo.name)

    def undo(self) -> bool:
        return self.keeper.undo()

    def redo(self) -> bool:
        return self.keeper.redo()

    def reset_everything(self) -> None:
        self.keeper.reset()


def compare_table(view_a: PosteriorView, view_b: PosteriorView) -> str:
    """Markdown: A's and B's mean uncertainty of the whole body and the limb ends, and B ÷ A."""
    numbers_a, numbers_b = limb_uncertainty_cm(view_a), limb_uncertainty_cm(view_b)
    if numbers_a is None or numbers_b is None:
        ratio = float(np.mean(view_b.uncertainty) / max(np.mean(view_a.uncertainty), 1e-9))
        return f"Mean uncertainty B ÷ A: {ratio:.2f}×"
    rows = "\n".join(
        f"| {name} | {cm:.1f} | {numbers_b[name]:.1f} | {numbers_b[name] / cm:.2f}× |"
        for name, cm in numbers_a.items()
    )
    return "| part | A cm | B cm | B ÷ A |\n|---|---:|---:|---:|\n" + rows
