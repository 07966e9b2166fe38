"""What the explorer needs from a predictor, as a small protocol, and the adapter to the real one.

The app only calls ``provider.predict(image, occluders, evidence=..., bbox=...)`` and reads the
posterior and (when there is one) the proxy representation from the result, so anything with
that method can drive it: the library's :class:`hkpd.prediction.Predictor`, or a test double in
the test suite. A provider that also has ``find_people`` (:class:`PeopleFinder`) lets the user
choose among several people in a photo; one with ``fits_person_mask`` (:class:`MaskFittingProvider`)
also takes ``silhouette=True`` and gets the *Fit the person mask* switch; one with
``states_body`` (:class:`BodyStatingProvider`) also takes ``sex=`` and ``measurements=`` (what
the user states in the Body section; only with ``evidence``).
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np
import torch

from hkpd.explorer.body_settings import BodyStatement
from hkpd.prediction.detection.keypoint_detector import people_by_size, reading_box
from hkpd.prediction.posterior import BodyPosterior
from hkpd.prediction.predictor import Predictor, refuse_silhouette_model
from hkpd.stated_body import StatedValue

Box = tuple[float, float, float, float]


@dataclass(frozen=True)
class PredictionResult:
    """One prediction for one photo and set of occluders.

    Attributes:
        posterior: the body distribution.
        proxy: ``(18, 256, 256)`` float proxy representation the network saw (edge image, then
            17 joint heatmaps), or None when the provider does not expose it.
    """

    posterior: BodyPosterior
    proxy: torch.Tensor | None = None


class PosteriorProvider(Protocol):
    """Anything that turns a photo and occluder boxes into a :class:`PredictionResult`."""

    def predict(
        self,
        image: np.ndarray,
        occluders: Sequence[Box],
        evidence: bool = True,
        bbox: Box | None = None,
    ) -> PredictionResult:
        """Predict for ``image`` ``(H, W, 3)`` uint8 RGB with ``occluders`` painted black.

        Args:
            image: the photo, original pixels.
            occluders: ``(x0, y0, x1, y1)`` boxes in the photo's pixels (may be empty).
            evidence: condition on the photo's 2D keypoints (else the network alone).
            bbox: look for the person only inside this box (None: anywhere).
        """
        ...


class MaskFittingProvider(PosteriorProvider, Protocol):
    """A provider that can also fit the photo's person mask (optional for providers): the
    explorer's *Fit the person mask* switch is offered only when ``fits_person_mask`` is True."""

    fits_person_mask: bool

    def predict(
        self,
        image: np.ndarray,
        occluders: Sequence[Box],
        evidence: bool = True,
        bbox: Box | None = None,
        silhouette: bool = False,
    ) -> PredictionResult:
        """As :meth:`PosteriorProvider.predict`; ``silhouette``: with ``evidence``, fit the
        person mask (BlazePose's segmentation, the silhouette term) as well as the keypoints."""
        ...


class BodyStatingProvider(PosteriorProvider, Protocol):
    """A provider that can condition the body on what the user states (optional for
    providers): the Body section's menu and fields work only when ``states_body`` is True."""

    states_body: bool

    def predict(
        self,
        image: np.ndarray,
        occluders: Sequence[Box],
        evidence: bool = True,
        bbox: Box | None = None,
        sex: str | None = None,
        measurements: dict[str, StatedValue] | None = None,
    ) -> PredictionResult:
        """As :meth:`PosteriorProvider.predict`; ``sex`` ("female", "male") and
        ``measurements`` (``{name: value | (value, std)}``, metres and kilograms) condition the
        shape (only with ``evidence``; see :meth:`hkpd.prediction.Predictor.predict`)."""
        ...


def body_arguments(provider: object, stated: BodyStatement, evidence: bool) -> dict[str, object]:
    """The keyword arguments that pass ``stated`` to ``provider``: empty when nothing is
    stated, without ``evidence`` (a stated value conditions the evidence posterior only) or
    for a provider that cannot take them (not ``states_body``)."""
    if stated.empty or not evidence or not getattr(provider, "states_body", False):
        return {}
    return stated.predict_arguments()


class PeopleFinder(Protocol):
    """A provider that can also list every person in a photo (optional for providers)."""

    def find_people(self, image: np.ndarray) -> list[Box]:
        """The ``(x0, y0, x1, y1)`` box (photo pixels) of each person found in ``image``
        ``(H, W, 3)`` uint8 RGB, best first; empty when nobody is found."""
        ...


class PredictorProvider:
    """Adapter from :class:`hkpd.prediction.Predictor` to :class:`PosteriorProvider`.

    The predictor is loaded on construction (``Predictor.from_pretrained(path, device)``).
    The proxy shown is ``posterior.network_input.proxy``, what the network saw.
    """

    @property
    def states_body(self) -> bool:
        """The body model has sex priors, so a sex and measurements can be stated."""
        return bool(self.predictor.body.has_sex_priors)

    fits_person_mask = True

    def __init__(self, path: str | Path | None = None, device: str = "auto") -> None:
        self.predictor: Predictor = Predictor.from_pretrained(path, device=device)
        refuse_silhouette_model(self.predictor, "the explorer")
        self._lock = threading.Lock()

    def predict(
        self,
        image: np.ndarray,
        occluders: Sequence[Box],
        evidence: bool = True,
        bbox: Box | None = None,
        silhouette: bool = False,
        sex: str | None = None,
        measurements: dict[str, StatedValue] | None = None,
    ) -> PredictionResult:
        boxes = [tuple(map(float, box)) for box in occluders] or None
        with self._lock:  # the predictor's switch holds for this call only
            self.predictor.silhouette_evidence = silhouette
            posterior = self.predictor.predict(
                image, occluders=boxes, bbox=bbox, evidence=evidence, sex=sex,
                measurements=measurements,
            )  # fmt: skip
        return PredictionResult(posterior=posterior, proxy=posterior.network_input.proxy.cpu())

    def find_people(self, image: np.ndarray) -> list[Box]:
        """Every person the detector lists (``detect_all``: BlazePose's detector and NanoDet's
        person boxes), each as the box that reads them (:func:`~hkpd.prediction.detection.
        keypoint_detector.reading_box`: their person box, or their landmarks' box), larger
        people first (:func:`hkpd.prediction.detection.keypoint_detector.people_by_size`)."""
        detections = people_by_size(self.predictor.detector.detect_all(image))
        return [tuple(float(v) for v in reading_box(d)) for d in detections]
