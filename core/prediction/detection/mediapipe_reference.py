"""The legacy MediaPipe BlazePose solution, kept only as the reference for parity checks.

hkpd runs BlazePose itself (:mod:`hkpd.prediction.detection.blazepose`); this module wraps
``mediapipe.solutions.pose.Pose`` (``static_image_mode=True``, ``model_complexity=1``, the same
two models) so that ``benchmarks/bench_keypoint_parity.py`` and the parity test can compare the
two where mediapipe is installed. mediapipe is NOT a dependency of hkpd: constructing
:class:`MediapipePose` without it raises ``ModuleNotFoundError`` with advice.
"""

from __future__ import annotations

import importlib
from collections.abc import Sequence

import numpy as np

from hkpd.prediction.detection.boxes import search_region, validated_box
from hkpd.prediction.image_input import LoadedImage, load_image


class MediapipePose:
    """BlazePose 33 landmarks of one person from the legacy mediapipe solution.

    Args:
        min_detection_confidence: the person detector's score threshold.
    """

    def __init__(self, min_detection_confidence: float = 0.5) -> None:
        try:
            solution = importlib.import_module("mediapipe.python.solutions.pose")
        except ModuleNotFoundError as error:
            raise ModuleNotFoundError(
                "the mediapipe reference needs `pip install mediapipe==0.10.21` (numpy<2); hkpd "
                "itself does not use it"
            ) from error
        self._pose = solution.Pose(
            static_image_mode=True,
            model_complexity=1,
            enable_segmentation=False,
            min_detection_confidence=min_detection_confidence,
        )

    def close(self) -> None:
        """Release the MediaPipe graph."""
        self._pose.close()

    def landmarks(
        self, image: LoadedImage | np.ndarray | str, bbox: Sequence[float] | None = None
    ) -> np.ndarray | None:
        """``(33, 3)`` float64 ``(u, v, visibility)`` in original-photo pixels, or None.

        ``bbox`` restricts the search like :meth:`hkpd.prediction.KeypointDetector.detect`.
        """
        loaded = load_image(image)
        x0, y0, x1, y1 = 0, 0, *loaded.size
        if bbox is not None:
            x0, y0, x1, y1 = search_region(loaded, validated_box(bbox, loaded.original_size))
        result = self._pose.process(np.ascontiguousarray(loaded.pixels[y0:y1, x0:x1]))
        if result.pose_landmarks is None:
            return None
        raw = np.array(
            [(lm.x, lm.y, lm.visibility) for lm in result.pose_landmarks.landmark], np.float64
        )
        # MediaPipe's normalised x is 0 at the region's left edge, 1 at its right edge.
        working = raw[:, :2] * np.array([x1 - x0, y1 - y0]) - 0.5 + np.array([x0, y0])
        return np.concatenate([loaded.to_original(working), raw[:, 2:]], axis=1)
