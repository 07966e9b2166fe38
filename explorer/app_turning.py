"""The app's *Turn around* action (the photo tab's "Facing" folder,
:mod:`hkpd.explorer.panels.turn`), as a mixin of :class:`~hkpd.explorer.app.ExplorerApp`.

The setting is part of the state (:attr:`~hkpd.explorer.state.ExplorerState.turned_around`: a
new photo starts as read) and of scene files. Every prediction of the person goes through
:meth:`TurnAppActions._turned`: with the setting on, the predicted evidence posterior is
replaced by its :meth:`~hkpd.prediction.BodyPosterior.turned_around` reading (a second fit of
the keypoints, ~0.2-0.5 s on a CPU), so occluder edits, the change colouring's baseline and
compare's ``no-occluders`` B all show the turned person. A posterior that cannot be turned
(the network alone, a fit that fell back, a custom provider's) is shown as predicted, and the
folder says why.

The button itself does not predict again when nothing else changed since the person was last
predicted (:meth:`TurnAppActions._turn_job`): it turns that reading (or shows it as read), so
a click costs the turned fit alone.
"""

from __future__ import annotations

import threading
import time
from typing import TYPE_CHECKING

from hkpd.explorer.progress import PREDICT
from hkpd.explorer.provider import PredictionResult

if TYPE_CHECKING:
    from hkpd.explorer.app import ExplorerApp
    from hkpd.explorer.state import StateSnapshot

    _Base = ExplorerApp
else:
    _Base = object


def turned_result(result: PredictionResult, wanted: bool) -> tuple[PredictionResult, str]:
    """``result`` with its posterior turned around when ``wanted`` (and not turned already),
    and "" or why it could not be turned (then ``result`` as it was)."""
    posterior = result.posterior
    if not wanted or getattr(posterior, "turned", False):
        return result, ""
    try:
        turned = posterior.turned_around()
    except (AttributeError, ValueError) as error:
        return result, str(error) if isinstance(error, ValueError) else "not a photo's posterior"
    return PredictionResult(turned, result.proxy), ""


class TurnAppActions(_Base):
    """*Turn around* for :class:`ExplorerApp`."""

    _turn_reason = ""
    _turn_lock = threading.Lock()
    _read: tuple[tuple, PredictionResult] | None = None

    def set_turned_around(self, enabled: bool) -> None:
        """Show the turned-around reading of the person (True) or the reading as predicted
        (the panel's button and the scene files call this; :meth:`_turn_job`)."""
        changed = self.state.set_turned_around(enabled)
        self.panels.turn.show(self.state.turned_around, None)
        if changed:
            self.worker.submit("predict", self._turn_job)

    def _turn_job(self) -> None:
        """Show the last reading of the person turned as the state asks, when it was predicted
        from what the state holds now; otherwise (an edit still pending, another photo)
        predict again."""
        snapshot = self.state.snapshot()
        with self._lock:
            image, token = self._image, self._image_token
        inputs = _reading_inputs(self, token, snapshot)
        with self._turn_lock:
            read = self._read if self._read is not None and self._read[0] == inputs else None
        if read is None:
            self._predict_job()
            return
        started = time.perf_counter()
        self.progress.step(PREDICT)
        self._show_reading(self._turned(read[1]), image, token, snapshot, started)

    def _remember_reading(
        self, token: int, snapshot: StateSnapshot, result: PredictionResult
    ) -> None:
        """Keep ``result``, the person's reading as predicted (before any turn) from photo
        ``token`` and ``snapshot``, for :meth:`_turn_job`."""
        with self._turn_lock:
            self._read = (_reading_inputs(self, token, snapshot), result)

    def _turned(self, result: PredictionResult, turned: bool | None = None) -> PredictionResult:
        """``result`` turned around when ``turned`` (None: the state's setting) asks for it;
        keeps why it could not be for the folder's line."""
        wanted = self.state.turned_around if turned is None else turned
        shown, reason = turned_result(result, wanted)
        if turned is None:  # the person's own prediction (not a baseline's or B's)
            with self._turn_lock:
                self._turn_reason = reason
        return shown

    def _compare_predict(self, *arguments) -> PredictionResult:
        """Compare's predictions of B (``no-occluders``, ``network``): A's model, turned as A
        is (a network-only B cannot be turned and stays as read)."""
        return self._turned(self._provider_predict(*arguments), self.state.turned_around)

    def _show_turn(self, posterior: object | None) -> None:
        """The folder's button and line for the shown ``posterior`` (None: nobody found)."""
        with self._turn_lock:
            reason = self._turn_reason
        shown = None if posterior is None else bool(getattr(posterior, "turned", False))
        self.panels.turn.show(self.state.turned_around, shown, reason)


def _reading_inputs(app: TurnAppActions, token: int, snapshot: StateSnapshot) -> tuple:
    """What the person's prediction is made from: the photo, the provider, the occluders, the
    evidence switches, the person box, the stated body and the other photos of the person."""
    return (
        token, id(app.provider), tuple(snapshot.active_boxes), snapshot.evidence,
        snapshot.silhouette, snapshot.person_box, snapshot.stated,
        tuple(id(photo) for photo in snapshot.same_person),
    )  # fmt: skip
