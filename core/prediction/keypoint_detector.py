"""COCO-17 2D keypoints of one person in a photo, from MediaPipe's BlazePose.

:class:`KeypointDetector` wraps the legacy ``mediapipe.solutions.pose.Pose`` (BlazePose full
model, ``model_complexity=1``, whose weights ship inside the mediapipe wheel: nothing is
downloaded). BlazePose finds 33 landmarks of ONE person; the 17 COCO keypoints are a subset
(:data:`COCO_FROM_BLAZEPOSE`), and each keypoint's confidence is BlazePose's landmark
``visibility`` in [0, 1].

With several people in the photo, BlazePose takes one of them (usually the largest, most
central); pass ``bbox`` to :meth:`KeypointDetector.detect` to restrict the search to one region.
:attr:`KeypointDetection.person_box` says which person was taken.

Coordinates are ``(u, v)`` pixels of the ORIGINAL photo (see :mod:`hkpd.prediction.image_input`),
pixel centres at integer coordinates. MediaPipe's normalised landmark ``x`` spans the image from
its left edge (0) to its right edge (1), so ``u = x * width - 0.5``.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hkpd.prediction.image_input import LoadedImage, load_image

COCO_FROM_BLAZEPOSE = (0, 2, 5, 7, 8, 11, 12, 13, 14, 15, 16, 23, 24, 25, 26, 27, 28)
"""BlazePose landmark index of each COCO-17 keypoint, in COCO order (nose, left eye, right eye,
left ear, right ear, left/right shoulder, elbow, wrist, hip, knee, ankle)."""

BLAZEPOSE_MODEL_COMPLEXITY = 1
"""The BlazePose "full" model: the only one in the mediapipe wheel (0 and 2 need a download)."""

SEARCH_BOX_PADDING = 0.1
"""A ``bbox`` search region is widened by this fraction of its width/height on every side, so
that a tight box does not cut off the hands or feet the detector needs to see."""

MIN_SEARCH_REGION = 16
"""Smallest search region side, in working-image pixels, that is worth running the detector on."""

MIN_CONFIDENT_KEYPOINTS = 4
"""A detection with fewer COCO keypoints of confidence >= :data:`CONFIDENT_VISIBILITY` counts as
no person (BlazePose occasionally hallucinates a pose on clutter)."""

CONFIDENT_VISIBILITY = 0.5
"""Visibility at which a keypoint counts towards :data:`MIN_CONFIDENT_KEYPOINTS`."""

MASK_THRESHOLD = 0.5
"""Segmentation-mask value above which a pixel belongs to the person (for ``mask_box``)."""


class NoPersonFoundError(RuntimeError):
    """The detector found no person; the message suggests what to try."""


@dataclass(frozen=True)
class KeypointDetection:
    """One person's COCO-17 keypoints in original-photo pixels.

    Attributes:
        keypoints: ``(17, 2)`` float64 ``(u, v)`` in original-photo pixels, COCO order. Points
            BlazePose places outside the photo (out-of-frame limbs) are kept as predicted.
        confidences: ``(17,)`` float64 in [0, 1], BlazePose's landmark visibility.
        person_box: ``(4,)`` ``(x0, y0, x1, y1)`` bounding box of all 33 BlazePose landmarks,
            original pixels, clipped to the photo: which person was taken.
        mask_box: ``(4,)`` box of BlazePose's person segmentation mask (includes hair, hands and
            feet), original pixels; None unless the detector was made with ``segmentation=True``
            (or when the mask is empty).
        search_box: the ``bbox`` the search was restricted to (original pixels), or None.
        image_size: ``(width, height)`` of the original photo.
        seconds: wall time of the detector call (lock wait excluded), seconds.
    """

    keypoints: np.ndarray
    confidences: np.ndarray
    person_box: np.ndarray
    mask_box: np.ndarray | None
    search_box: np.ndarray | None
    image_size: tuple[int, int]
    seconds: float


class KeypointDetector:
    """BlazePose keypoint detector; one lazily created ``Pose`` graph reused across calls.

    Thread-safe: calls from several threads are serialised by a lock (the graph is stateful).
    Close it with :meth:`close` or use it as a context manager.

    Args:
        segmentation: also run BlazePose's person segmentation and report ``mask_box``
            (slower; see ``docs/prediction.md``).
        min_detection_confidence: BlazePose's person-detector threshold.
    """

    def __init__(self, segmentation: bool = False, min_detection_confidence: float = 0.5) -> None:
        self.segmentation = segmentation
        self.min_detection_confidence = min_detection_confidence
        self._pose: Any = None
        self._lock = threading.Lock()
        self._closed = False

    def __enter__(self) -> KeypointDetector:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def close(self) -> None:
        """Release the MediaPipe graph. A later :meth:`detect` raises."""
        with self._lock:
            if self._pose is not None:
                self._pose.close()
                self._pose = None
            self._closed = True

    def _graph(self) -> Any:
        """The ``Pose`` graph, created on first use (call with the lock held)."""
        if self._closed:
            raise RuntimeError("this KeypointDetector has been closed; create a new one")
        if self._pose is None:
            from mediapipe.python.solutions import pose as mp_pose

            self._pose = mp_pose.Pose(
                static_image_mode=True,
                model_complexity=BLAZEPOSE_MODEL_COMPLEXITY,
                enable_segmentation=self.segmentation,
                min_detection_confidence=self.min_detection_confidence,
            )
        return self._pose

    def detect(
        self,
        image: LoadedImage | np.ndarray | str,
        bbox: Sequence[float] | np.ndarray | None = None,
    ) -> KeypointDetection:
        """Detect one person's COCO-17 keypoints.

        Args:
            image: a :class:`LoadedImage` (coordinates are mapped back to its original photo),
                an ``(H, W, 3)`` uint8 RGB array, or anything else :func:`load_image` accepts.
            bbox: optional ``(x0, y0, x1, y1)`` in original-photo pixels: look for the person
                only there (widened by :data:`SEARCH_BOX_PADDING`, clipped to the photo).

        Returns:
            The :class:`KeypointDetection`.

        Raises:
            NoPersonFoundError: no person (or too few confident keypoints) in the image/region.
            ValueError: a malformed ``bbox``, or one outside the photo.
            ImageInputError: ``image`` could not be loaded.
        """
        loaded = load_image(image)
        region = (0, 0, *loaded.size)
        search_box = None
        if bbox is not None:
            search_box = _validated_box(bbox, loaded.original_size)
            region = _search_region(loaded, search_box)
        x0, y0, x1, y1 = region
        pixels = np.ascontiguousarray(loaded.pixels[y0:y1, x0:x1])

        with self._lock:
            graph = self._graph()
            start = time.perf_counter()
            result = graph.process(pixels)
            seconds = time.perf_counter() - start

        if result.pose_landmarks is None:
            raise NoPersonFoundError(_no_person_message(loaded, search_box))
        landmarks = np.array(
            [(lm.x, lm.y, lm.visibility) for lm in result.pose_landmarks.landmark], np.float64
        )
        region_size = np.array([x1 - x0, y1 - y0], np.float64)
        working = landmarks[:, :2] * region_size - 0.5 + np.array([x0, y0], np.float64)
        original = loaded.to_original(working)
        confidences = np.clip(landmarks[list(COCO_FROM_BLAZEPOSE), 2], 0.0, 1.0)
        if int((confidences >= CONFIDENT_VISIBILITY).sum()) < MIN_CONFIDENT_KEYPOINTS:
            raise NoPersonFoundError(
                _no_person_message(loaded, search_box)
                + f" (a pose was found but fewer than {MIN_CONFIDENT_KEYPOINTS} keypoints were "
                "visible with confidence)"
            )
        mask_box = None
        if result.segmentation_mask is not None:
            mask_box = _mask_box(result.segmentation_mask, loaded, (x0, y0))
        return KeypointDetection(
            keypoints=original[list(COCO_FROM_BLAZEPOSE)],
            confidences=confidences,
            person_box=_clipped_box(original, loaded.original_size),
            mask_box=mask_box,
            search_box=search_box,
            image_size=loaded.original_size,
            seconds=seconds,
        )


def _validated_box(bbox: Sequence[float] | np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """``(4,)`` float64 box after checking shape, order and overlap with the photo."""
    box = np.asarray(bbox, dtype=np.float64)
    if box.shape != (4,) or not np.isfinite(box).all():
        raise ValueError(f"bbox must be four finite numbers (x0, y0, x1, y1), got {bbox!r}")
    x0, y0, x1, y1 = box
    if x1 <= x0 or y1 <= y0:
        raise ValueError(f"bbox must have x1 > x0 and y1 > y0 (x0, y0, x1, y1), got {bbox!r}")
    width, height = image_size
    if x1 <= 0 or y1 <= 0 or x0 >= width or y0 >= height:
        raise ValueError(
            f"bbox {tuple(box)} lies outside the {width}x{height} photo; give it in pixels of "
            "the original photo as displayed (x0, y0, x1, y1)"
        )
    return box


def _search_region(loaded: LoadedImage, box: np.ndarray) -> tuple[int, int, int, int]:
    """Integer working-image slice bounds of the padded, clipped search box."""
    pad = SEARCH_BOX_PADDING * np.array([box[2] - box[0], box[3] - box[1]])
    corners = np.array([box[:2] - pad, box[2:] + pad])
    # Box corners are pixel edges; map them as edges (centre coordinates + 0.5).
    edges = loaded.from_original(corners - 0.5) + 0.5
    width, height = loaded.size
    x0, y0 = np.clip(np.floor(edges[0]), 0, [width, height]).astype(int)
    x1, y1 = np.clip(np.ceil(edges[1]), 0, [width, height]).astype(int)
    if min(x1 - x0, y1 - y0) < MIN_SEARCH_REGION:
        raise ValueError(
            f"bbox {tuple(box)} covers only {x1 - x0}x{y1 - y0} pixels of the photo; draw a "
            "box around the whole person"
        )
    return int(x0), int(y0), int(x1), int(y1)


def _clipped_box(points: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """Bounding box ``(x0, y0, x1, y1)`` of ``(N, 2)`` points, clipped to the photo's pixels."""
    width, height = image_size
    low = np.clip(points.min(0), -0.5, [width - 0.5, height - 0.5])
    high = np.clip(points.max(0), -0.5, [width - 0.5, height - 0.5])
    return np.concatenate([low, high])


def _mask_box(mask: np.ndarray, loaded: LoadedImage, offset: tuple[int, int]) -> np.ndarray | None:
    """Box of the segmentation mask's person pixels (centres), in original-photo pixels."""
    rows = np.flatnonzero((mask > MASK_THRESHOLD).any(1))
    cols = np.flatnonzero((mask > MASK_THRESHOLD).any(0))
    if rows.size == 0:
        return None
    corners = np.array([[cols[0], rows[0]], [cols[-1], rows[-1]]], np.float64) + offset
    return loaded.to_original(corners).reshape(4)


def _no_person_message(loaded: LoadedImage, search_box: np.ndarray | None) -> str:
    where = "in the photo" if search_box is None else f"inside bbox {tuple(search_box)}"
    hint = (
        "pass --bbox x0,y0,x1,y1 around the person (several people, or a small person)"
        if search_box is None
        else "check the bbox covers the whole person, in pixels of the original photo"
    )
    return (
        f"{loaded.source}: no person found {where}; {hint}, or use a photo where the person is "
        "large, well lit and mostly in the frame"
    )
