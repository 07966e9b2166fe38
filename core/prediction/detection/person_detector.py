"""Whole-person boxes from NanoDet, the COCO object detector that ships in
``hkpd.assets/human_models`` (run by :mod:`hkpd.model_runtime`).

BlazePose's own detector finds people by their face and torso, so it misses people seen from
behind, small or partly hidden; :class:`PersonDetector` boxes every person (COCO class 0) so
that :meth:`~hkpd.prediction.detection.keypoint_detector.KeypointDetector.detect_all` can read
the ones BlazePose's detector missed in their boxes.

The pre- and post-processing (measured on ``coco_mini`` train2017, 142 non-crowd people;
``docs/experiments/person_detector_eval.py``):

- :func:`letterboxed`: the photo scaled so its longer side is 416 pixels, at the top-left of a
  black 416 × 416 square (bilinear), then NanoDet's own normalisation: BGR channels,
  ``(value - mean) / std`` on 0..255 (:data:`NANODET_MEAN`, :data:`NANODET_STD`). AP50 0.67,
  against 0.50 for the photo stretched to the square in RGB 0..1 as the Human library feeds it
  (the graph holds no normalisation: its first ops are a Pad and a Conv2D).
- :func:`decoded_boxes`: per stride 8, 16, 32 (52², 26², 13² cells, row-major), the cell's
  centre ``((column + 0.5) s, (row + 0.5) s)`` and four distances left, top, right, bottom,
  each the expectation of a softmax over 11 bins (0..10 strides: Generalized Focal Loss's
  distribution; the 44 values are side-major). The ``+ 0.5`` measured (stretched RGB 0..1
  input): AP50 0.50 against 0.42 without, matched boxes' mean IoU 0.72 against 0.65.
- :func:`suppressed`: greedy non-maximum suppression at IoU :data:`NMS_IOU`.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch
from PIL import Image

from hkpd.model_runtime.shipped import load_human_model
from hkpd.prediction.detection.boxes import box_iou

__all__ = [
    "NANODET_SIZE",
    "PERSON_SCORE_THRESHOLD",
    "PersonBox",
    "PersonDetector",
    "decoded_boxes",
    "letterboxed",
    "suppressed",
]

NANODET_SIZE = 416
"""Side of NanoDet's square input, pixels."""

NANODET_STRIDES = (8, 16, 32)
"""Cell size of each output level, input pixels (52², 26², 13² cells)."""

NANODET_BINS = 11
"""Bins of each side's distance distribution (0..10 strides)."""

NANODET_OUTPUTS = (
    ("Identity", "Identity_3"),
    ("Identity_1", "Identity_4"),
    ("Identity_2", "Identity_5"),
)
"""``(class scores, box distributions)`` output names per stride of :data:`NANODET_STRIDES`."""

NANODET_MEAN = np.array([103.53, 116.28, 123.675], np.float32)
"""NanoDet's per-channel mean, BGR order, 0..255."""

NANODET_STD = np.array([57.375, 57.12, 58.395], np.float32)
"""NanoDet's per-channel standard deviation, BGR order, 0..255."""

PERSON_CLASS = 0
"""COCO's class index of a person."""

PERSON_SCORE_THRESHOLD = 0.35
"""Boxes scoring below this are not people (chosen on coco_mini train2017 with
``benchmarks/bench_person_search.py``: see docs/prediction.md, Person menu)."""

NMS_IOU = 0.6
"""Two boxes overlapping this much (IoU) are one person: the lower-scored one is dropped."""


@dataclass(frozen=True)
class PersonBox:
    """One person boxed by NanoDet.

    Attributes:
        box: ``(4,)`` float64 ``(x0, y0, x1, y1)`` pixels of the array the detector was given
            (original-photo pixels from :meth:`PersonDetector.find_in_photo`), clipped to it.
        score: NanoDet's person score in [0, 1].
    """

    box: np.ndarray
    score: float


def letterboxed(pixels: np.ndarray) -> tuple[torch.Tensor, float]:
    """NanoDet's input for an ``(H, W, 3)`` uint8 RGB image.

    Returns:
        ``(1, 3, 416, 416)`` float32 NCHW tensor (BGR, normalised; black padding right and
        below), and the scale (input pixels per image pixel).

    Raises:
        ValueError: ``pixels`` is not an ``(H, W, 3)`` image.
    """
    if pixels.ndim != 3 or pixels.shape[2] != 3 or min(pixels.shape[:2]) < 1:
        raise ValueError(f"expected an (H, W, 3) RGB image, got shape {pixels.shape}")
    height, width = pixels.shape[:2]
    scale = NANODET_SIZE / max(width, height)
    size = (max(1, round(width * scale)), max(1, round(height * scale)))
    resized = Image.fromarray(np.ascontiguousarray(pixels, np.uint8)).resize(
        size, Image.Resampling.BILINEAR
    )
    square = np.zeros((NANODET_SIZE, NANODET_SIZE, 3), np.float32)
    square[: size[1], : size[0]] = np.asarray(resized, np.float32)
    normalised = (square[..., ::-1] - NANODET_MEAN) / NANODET_STD
    return torch.from_numpy(np.ascontiguousarray(normalised.transpose(2, 0, 1)[None])), scale


def decoded_boxes(
    outputs: dict[str, torch.Tensor], class_index: int = PERSON_CLASS
) -> tuple[np.ndarray, np.ndarray]:
    """Every cell's box and score for one class, from NanoDet's six outputs.

    Args:
        outputs: the model's outputs by name (:data:`NANODET_OUTPUTS`): scores ``(1, cells,
            80)`` and distributions ``(1, cells, 44)`` per stride.
        class_index: the COCO class (0: person).

    Returns:
        ``(boxes (N, 4), scores (N,))`` float64, boxes ``(x0, y0, x1, y1)`` in input pixels
        (0..416), N = 52² + 26² + 13² = 3549 cells.
    """
    boxes, scores = [], []
    for stride, (score_name, box_name) in zip(NANODET_STRIDES, NANODET_OUTPUTS, strict=True):
        cells = NANODET_SIZE // stride
        logits = outputs[box_name][0].double().reshape(cells * cells, 4, NANODET_BINS)
        bins = torch.arange(NANODET_BINS, dtype=torch.float64)
        distance = (torch.softmax(logits, dim=-1) * bins).sum(-1).numpy() * stride
        index = np.arange(cells * cells)
        centre_u = (index % cells + 0.5) * stride
        centre_v = (index // cells + 0.5) * stride
        boxes.append(
            np.stack(
                [
                    centre_u - distance[:, 0],
                    centre_v - distance[:, 1],
                    centre_u + distance[:, 2],
                    centre_v + distance[:, 3],
                ],
                axis=1,
            )
        )
        scores.append(outputs[score_name][0, :, class_index].double().numpy())
    return np.concatenate(boxes), np.concatenate(scores)


def suppressed(boxes: np.ndarray, scores: np.ndarray, iou: float = NMS_IOU) -> list[int]:
    """Greedy non-maximum suppression: indices of the kept boxes, highest score first.

    Args:
        boxes: ``(N, 4)`` ``(x0, y0, x1, y1)``.
        scores: ``(N,)``.
        iou: a box overlapping a kept, higher-scored one by this much or more is dropped.
    """
    kept: list[int] = []
    for index in np.argsort(-scores, kind="stable"):
        if all(box_iou(boxes[index], boxes[other]) < iou for other in kept):
            kept.append(int(index))
    return kept


def _default_model() -> Callable[[torch.Tensor], dict[str, torch.Tensor]]:
    """The shipped NanoDet as a function of its input tensor."""
    model = load_human_model("nanodet")
    return lambda batch: model.run({"input_1": batch})


class PersonDetector:
    """People boxed by NanoDet; the model is loaded on first use, calls are serialised by a
    lock.

    Args:
        threshold: the person score from which a box is a person.
        model: NanoDet as a function ``(1, 3, 416, 416) tensor -> outputs by name`` (default:
            the shipped model; a stand-in in tests).
    """

    def __init__(
        self,
        threshold: float = PERSON_SCORE_THRESHOLD,
        model: Callable[[torch.Tensor], dict[str, torch.Tensor]] | None = None,
    ) -> None:
        self.threshold = threshold
        self._model = model
        self._lock = threading.Lock()

    def find(self, pixels: np.ndarray) -> list[PersonBox]:
        """The people in an ``(H, W, 3)`` uint8 RGB image, highest score first, boxes in its
        pixels (clipped to it), after non-maximum suppression."""
        batch, scale = letterboxed(pixels)
        with self._lock, torch.inference_mode():
            if self._model is None:
                self._model = _default_model()
            outputs = self._model(batch)
        boxes, scores = decoded_boxes(outputs)
        candidates = np.flatnonzero(scores >= self.threshold)
        boxes, scores = boxes[candidates] / scale, scores[candidates]
        height, width = pixels.shape[:2]
        boxes = np.clip(boxes, 0, [width, height, width, height])
        return [
            PersonBox(boxes[index], float(scores[index])) for index in suppressed(boxes, scores)
        ]
