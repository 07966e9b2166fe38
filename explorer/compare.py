"""Compare: a second posterior (B) for one alternative setting of the same photo and person.

The explorer's own columns show posterior A (what the panel says: this model, these boxes,
these concentrations). With a compare setting on, B is predicted beside it and drawn in a
second set of columns (:mod:`hkpd.explorer.compare_scene`):

* ``network``: the network alone (no keypoint evidence), same boxes (the reading A's fit
  updated, when A has one: :func:`network_reading`);
* ``no-occluders``: the same evidence setting without any box;
* ``default-concentrations``: the same posterior with every concentration factor at 1×;
* a checkpoint path: another model (e.g. the ablation's ``independent_samples.pt`` beside
  ``hierarchical_samples.pt``) on the same photo, person box, boxes and evidence.

B is sampled with A's seed and count and A's concentration factors (except for
``default-concentrations``), and its per-vertex uncertainty divided by A's is the change
colouring between the two (B ÷ A). B is predicted once per prediction of A (an occluder
edit costs two predictions; for ``network`` one, when A's fit kept the network's reading) and
sampled once per slider move (a slider move costs two draws;
B's most likely body is computed once per prediction, and its columns' titles, colour bar and
heatmap positions are sent again only when they change).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from hkpd.explorer.posterior_view import MIN_BASELINE_M, PosteriorView, compute_view
from hkpd.explorer.provider import (
    Box,
    PosteriorProvider,
    PredictionResult,
    PredictorProvider,
    body_arguments,
)
from hkpd.explorer.state import StateSnapshot
from hkpd.prediction.posterior import BodyMeshes, BodyPosterior

NAMED_SETTINGS: dict[str, str] = {
    "network": "network only",
    "no-occluders": "without the boxes",
    "default-concentrations": "concentrations at 1×",
}
"""The compare settings that need no file: command-line word -> what B is, in words."""

Predict = Callable[[np.ndarray, Sequence[Box], bool, bool, Box | None], PredictionResult]
"""``(image, boxes, evidence, silhouette, person_box) -> PredictionResult`` with A's model."""


@dataclass(frozen=True)
class CompareSetting:
    """What B differs in from A.

    Attributes:
        kind: a key of :data:`NAMED_SETTINGS`, or ``"model"``.
        checkpoint: the other model's checkpoint (``kind == "model"`` only).
    """

    kind: str
    checkpoint: str | None = None

    @property
    def text(self) -> str:
        """The setting as given on the command line and stored in scene files."""
        return self.checkpoint if self.kind == "model" else self.kind  # type: ignore[return-value]

    @property
    def label(self) -> str:
        """What B is, in a few words ("network only", "model independent_samples.pt")."""
        if self.kind == "model":
            return f"model {Path(str(self.checkpoint)).name}"
        return NAMED_SETTINGS[self.kind]


def parse_compare(text: str) -> CompareSetting:
    """A compare setting from its command-line form: a word of :data:`NAMED_SETTINGS` or the
    path of a checkpoint file.

    Raises:
        ValueError: neither a known word nor an existing file.
    """
    word = text.strip()
    if word in NAMED_SETTINGS:
        return CompareSetting(word)
    if Path(word).is_file():
        return CompareSetting("model", str(Path(word)))
    raise ValueError(
        f"--compare {text!r}: use one of {', '.join(NAMED_SETTINGS)}, or the path of a model "
        "checkpoint (that file does not exist)"
    )


def _sampling_key(snapshot: StateSnapshot) -> tuple:
    """What a view's draw depends on besides the posterior (not the sampling version, which
    every slider of A moves)."""
    return (
        snapshot.joint_exponents, snapshot.global_exponent, snapshot.shape_std_exponent,
        snapshot.num_samples, snapshot.num_displayed, snapshot.seed, snapshot.selected_joint,
    )  # fmt: skip


def network_reading(posterior: BodyPosterior) -> BodyPosterior | None:
    """The network's own posterior that ``posterior``'s keypoint fit updated (its ``prior``:
    the same photo, boxes and crop), or None when there is none (the network alone, a fit
    that fell back, a turned-around reading, a custom provider's posterior).

    It is what predicting with the evidence off returns: the reading stage does not depend on
    the evidence (on the shipped photo the two are bit-identical with no box and with boxes
    over the right shin, the left elbow and the right forearm; ``tests/
    test_explorer_compare_real_model.py``), so compare's ``network`` B needs no second
    prediction."""
    prior = getattr(posterior, "prior", None)
    if prior is None or not getattr(posterior, "conditioned", False):
        return None
    return None if getattr(posterior, "turned", False) else prior


def _load_model(path: str) -> PosteriorProvider:
    return PredictorProvider(path, device="cpu")


@dataclass(frozen=True)
class ComparePrediction:
    """B's posterior for one prediction of A, and its most likely body (the same for every
    slider setting: :func:`~hkpd.explorer.posterior_view.compute_view`'s ``mode``), computed
    with B's first view and kept for the others."""

    setting: CompareSetting
    posterior: BodyPosterior
    mode: list[BodyMeshes] = field(default_factory=list, compare=False)


class Comparison:
    """Holds the compare setting, B's posterior and B's last view; thread-safe.

    Args:
        predict: A's model (see :data:`Predict`).
        load_model: checkpoint path -> provider, for model settings (loaded once per path).
    """

    def __init__(
        self, predict: Predict, load_model: Callable[[str], PosteriorProvider] = _load_model
    ) -> None:
        self._predict, self._load_model = predict, load_model
        self._lock = threading.Lock()
        self._setting: CompareSetting | None = None
        self._models: dict[str, PosteriorProvider] = {}
        self._prediction: ComparePrediction | None = None
        self._view: PosteriorView | None = None
        self._error: str | None = None
        self._view_of: tuple[ComparePrediction, tuple] | None = None
        """The prediction and sampling key of :attr:`view`."""
        self.reused = False
        """The last :meth:`compute` kept B's draw (only the ratio to A changed)."""

    @property
    def error(self) -> str | None:
        """Why the last prediction of B failed (None when it did not)."""
        with self._lock:
            return self._error

    @property
    def setting(self) -> CompareSetting | None:
        with self._lock:
            return self._setting

    @property
    def view(self) -> PosteriorView | None:
        """B's last view (its ``change_ratio`` is B's uncertainty ÷ A's), or None."""
        with self._lock:
            return self._view

    def set_setting(self, setting: CompareSetting | None) -> bool:
        """Compare against ``setting`` (None: no comparison); loads a model setting's
        checkpoint now (so a bad file is refused at once). True if it changed.

        Raises:
            RuntimeError: the checkpoint cannot be loaded.
        """
        if setting is not None and setting.kind == "model":
            self._model(str(setting.checkpoint))
        with self._lock:
            if setting == self._setting:
                return False
            self._setting, self._prediction, self._view = setting, None, None
            self._error = None
            return True

    def clear(self) -> None:
        """Forget B (nobody was found, or a new photo)."""
        with self._lock:
            self._prediction, self._view = None, None

    def predict(self, image: np.ndarray, snapshot: StateSnapshot, result: PredictionResult) -> None:
        """Predict B for A's ``result`` on ``image`` with the snapshot's boxes and switches (a
        failure, e.g. B's model finds nobody, is kept in :attr:`error` and B is cleared)."""
        setting = self.setting
        if setting is None:
            self.clear()
            return
        try:
            posterior = self._predict_b(setting, image, snapshot, result)
        except Exception as error:  # B is an extra: say why it is missing, keep A
            with self._lock:
                self._prediction, self._view = None, None
                self._error = f"{type(error).__name__}: {error}"
            return
        with self._lock:
            if setting == self._setting:
                self._prediction, self._view = ComparePrediction(setting, posterior), None
                self._error = None

    def _predict_b(
        self,
        setting: CompareSetting,
        image: np.ndarray,
        snapshot: StateSnapshot,
        result: PredictionResult,
    ) -> BodyPosterior:
        boxes, box = snapshot.active_boxes, snapshot.person_box
        evidence, silhouette = snapshot.evidence, snapshot.silhouette
        if setting.kind == "default-concentrations":
            posterior = result.posterior
        elif setting.kind == "network":
            reading = network_reading(result.posterior)  # no second prediction when A has it
            if reading is None:
                reading = self._predict(image, boxes, False, False, box).posterior
            posterior = reading
        elif setting.kind == "no-occluders":
            posterior = self._predict(image, [], evidence, silhouette, box).posterior
        else:
            provider = self._model(str(setting.checkpoint))
            body = body_arguments(provider, snapshot.stated, evidence)  # the same person as A
            if evidence and silhouette and getattr(provider, "fits_person_mask", False):
                answer = provider.predict(image, boxes, True, box, silhouette=True, **body)  # type: ignore[call-arg]
            else:
                answer = provider.predict(image, boxes, evidence=evidence, bbox=box, **body)
            posterior = answer.posterior
        return posterior

    def compute(self, snapshot: StateSnapshot, view_a: PosteriorView) -> PosteriorView | None:
        """B's view for the sliders in ``snapshot`` (A's seed and count; A's factors unless
        the setting is ``default-concentrations``), with ``change_ratio`` = B ÷ A."""
        with self._lock:
            prediction = self._prediction
        if prediction is None:
            return None
        if prediction.setting.kind == "default-concentrations":
            snapshot = replace(
                snapshot,
                joint_exponents=(0.0,) * len(snapshot.joint_exponents),
                global_exponent=0.0,
                shape_std_exponent=0.0,
            )
        key = _sampling_key(snapshot)
        with self._lock:
            of = self._view_of
            same = of is not None and of[0] is prediction and of[1] == key
            cached = self._view if same else None
        if cached is None:  # B's draw changed (a slider B follows, the seed, a new prediction)
            if not prediction.mode:  # once per prediction: sliders never move the mode
                prediction.mode.append(prediction.posterior.mode())
            mode = prediction.mode[0]
            view = compute_view(prediction.posterior, snapshot, view_a.uncertainty, mode)
        else:  # only A moved (default-concentrations): the same B, a new ratio
            ratio = cached.uncertainty / np.maximum(view_a.uncertainty, MIN_BASELINE_M)
            view = replace(cached, change_ratio=ratio)
        self.reused = cached is not None
        with self._lock:
            if self._prediction is prediction:
                self._view, self._view_of = view, (prediction, key)
        return view

    def _model(self, path: str) -> PosteriorProvider:
        with self._lock:
            found = self._models.get(path)
        if found is not None:
            return found
        try:
            provider = self._load_model(path)
        except Exception as error:
            raise RuntimeError(f"cannot compare with {path}: {error}") from None
        with self._lock:
            return self._models.setdefault(path, provider)
