"""A second, independent keypoint reader: Google's MoveNet SinglePose Thunder (issue 59).

BlazePose (:mod:`hkpd.prediction.detection.keypoint_detector`) finds the person and reads their
keypoints; every quality signal used to come from it alone, so a reading BlazePose is sure of
and wrong about went unwarned. MoveNet Thunder (trained apart from BlazePose, COCO-17 keypoints,
run by :mod:`hkpd.model_runtime` from ``hkpd.assets/human_models``) reads the same person again:
:class:`SecondReader` cuts an upright square around the person (BlazePose's landmark box, or the
user's box when one was given), runs Thunder on it and maps its keypoints back to photo pixels.

Where the two agree, both are evidence; where they disagree, the reading is doubted
(:mod:`hkpd.prediction.reader_agreement`).

API::

    reader = SecondReader()                        # loads movenet-thunder on first use
    second = reader.read(loaded_image, detection)  # -> SecondReading (photo pixels)
    second = reader.read(loaded_image, detection, bbox=(x0, y0, x1, y1))  # the user's box
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import torch

from hkpd.model_runtime.shipped import load_human_model
from hkpd.prediction.detection.keypoint_detector import KeypointDetection
from hkpd.prediction.detection.warp import Region, crop
from hkpd.prediction.image_input import LoadedImage, load_image

__all__ = ["MOVENET_INPUT_SIZE", "SecondReader", "SecondReading", "reading_region"]

MOVENET_INPUT_SIZE = 256
"""Side of Thunder's input square, pixels."""

PERSON_BOX_PADDING = 1.25
"""The crop's side / the longer side of BlazePose's landmark box: MoveNet reads people that
fill about 80 % of its square (Google's own cropping grows the body's extent by 1.2)."""

USER_BOX_PADDING = 1.1
"""The crop's side / the longer side of the user's box (which is already loose)."""


@dataclass(frozen=True)
class SecondReading:
    """MoveNet Thunder's reading of one person.

    Attributes:
        keypoints: ``(17, 2)`` float64 ``(u, v)`` original-photo pixels, COCO order.
        scores: ``(17,)`` float64 in [0, 1], Thunder's keypoint scores.
        region: the upright square read, working-image pixels (:class:`Region`).
        seconds: wall time of the crop, the model and the mapping, seconds.
    """

    keypoints: np.ndarray
    scores: np.ndarray
    region: Region
    seconds: float

    def __repr__(self) -> str:
        confident = int(np.count_nonzero(self.scores >= 0.3))
        return (
            f"SecondReading(movenet-thunder, {confident} of 17 scored >= 0.3, {self.seconds:.3f} s)"
        )


def reading_region(
    image: LoadedImage, detection: KeypointDetection, bbox: Sequence[float] | None = None
) -> Region:
    """The upright square Thunder reads, in ``image``'s working pixels: centred on the user's
    ``bbox`` (original pixels) when given, else on BlazePose's landmark box
    (``detection.person_box``), its side the box's longer side × the padding."""
    if bbox is not None:
        box, padding = np.asarray(bbox, np.float64).ravel()[:4], USER_BOX_PADDING
    else:
        box, padding = np.asarray(detection.person_box, np.float64), PERSON_BOX_PADDING
    scale = np.asarray(image.scale, np.float64)
    low, high = box[:2] * scale, box[2:] * scale
    side = max(float((high - low).max()) * padding, 8.0)
    return Region(centre=(low + high) / 2, size=side, angle=0.0)


def _default_model() -> Callable[[torch.Tensor], torch.Tensor]:
    model = load_human_model("movenet-thunder")
    return lambda pixels: model.run({"input": pixels})["Identity"]


class SecondReader:
    """MoveNet Thunder as a second keypoint reader (module docstring). The model is loaded on
    first use; calls are serialised by a lock.

    Args:
        model: a callable ``(1, 256, 256, 3)`` int32 RGB 0..255 -> ``(1, 1, 17, 3)``
            ``(y, x, score)`` in 0..1 of the input (default: the shipped Thunder; tests pass a
            stand-in).
    """

    def __init__(self, model: Callable[[torch.Tensor], torch.Tensor] | None = None) -> None:
        self._model = model
        self._lock = threading.Lock()

    def read(
        self,
        image: LoadedImage | np.ndarray | str,
        detection: KeypointDetection,
        bbox: Sequence[float] | np.ndarray | None = None,
    ) -> SecondReading:
        """Thunder's reading of the person BlazePose found (``detection``), or of the user's
        ``bbox`` (original pixels) when given."""
        loaded = load_image(image)
        start = time.perf_counter()
        region = reading_region(loaded, detection, bbox)
        pixels = crop(loaded.pixels, region, MOVENET_INPUT_SIZE, replicate=False)
        batch = torch.from_numpy(np.ascontiguousarray(pixels)).to(torch.int32)[None]
        with self._lock, torch.no_grad():
            if self._model is None:
                self._model = _default_model()
            output = self._model(batch)
        values = np.asarray(output, np.float64).reshape(17, 3)
        working = region.to_photo(values[:, [1, 0]])
        keypoints = np.asarray(loaded.to_original(working), np.float64)
        seconds = time.perf_counter() - start
        return SecondReading(keypoints, np.clip(values[:, 2], 0.0, 1.0), region, seconds)
