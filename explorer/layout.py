"""Where the explorer's columns stand along the world x axis: the photo's right edge, the most
likely body (x = 0), the uncertainty body, the combined-shape body and the compare columns.

The row of columns is wider than the canvas left of the control panel is tall, so its width
sets the scale the bodies are drawn at. The fixed spacing (:data:`DEFAULT_LAYOUT`) leaves room
for outstretched arms on both bodies; :func:`column_layout` spaces the columns by the person's
real reach instead (the mode's leftmost and rightmost keypoints plus room for the hands and the
samples' spread), so a person with the arms down is drawn larger. The layout is chosen once per
photo (from its first prediction), so the columns do not move while boxes and sliders change.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

BODY_HALF_SPAN_M = 0.95
"""Most room a body gets on either side of its centre (outstretched arms reach ~0.85 m)."""
HAND_ROOM_M = 0.25
"""Room beyond the outermost keypoint (a wrist) for the hand and the samples' spread."""
MIN_REACH_M = 0.45
"""Least room on either side of a body's centre (arms down: the shoulder and the hip)."""
COLUMN_GAP_M = 0.1
"""Extra metres between two neighbouring bodies' reaches (and between the photo and the most
likely body's left reach: with the test double's left elbow hidden, its samples come within
0.02 m of the photo without it)."""
COMPARE_GROUP_GAP_M = 0.15
"""Extra metres between A's uncertainty body and B's most likely body."""
COMBINED_STEP_M = 1.9
"""Metres from the uncertainty body to the combined-shape body (a T-pose arm span + room)."""


@dataclass(frozen=True)
class ColumnLayout:
    """Column positions, world metres along x (the most likely body stands at x = 0).

    Attributes:
        photo_gap: from the photo's right edge to the most likely body's centre.
        step: from one body's centre to the next (most likely -> uncertainty, and B's two).
    """

    photo_gap: float = 0.9
    step: float = 1.75

    def __post_init__(self) -> None:
        if not (math.isfinite(self.photo_gap) and math.isfinite(self.step)):
            raise ValueError(f"column layout needs finite metres, got {self}")
        if self.photo_gap <= 0 or self.step <= 0:
            raise ValueError(f"column layout needs positive gaps, got {self}")

    @property
    def heat_x(self) -> float:
        """x of the uncertainty body."""
        return self.step

    @property
    def combined_x(self) -> float:
        """x of the combined-shape body (same person's photos)."""
        return self.heat_x + COMBINED_STEP_M

    @property
    def compare_body_x(self) -> float:
        """x of B's most likely body (with its samples)."""
        return self.heat_x + self.step + COMPARE_GROUP_GAP_M

    @property
    def compare_heat_x(self) -> float:
        """x of B's uncertainty body."""
        return self.compare_body_x + self.step


DEFAULT_LAYOUT = ColumnLayout()
"""The spacing for any pose (outstretched arms), used before a person is predicted and for
a provider without keypoints."""


def body_extent(result: object) -> tuple[float, float]:
    """Metres ``(left, right)`` of the body's centre its drawing reaches: the mode's leftmost
    and rightmost keypoints plus :data:`HAND_ROOM_M`, each within [:data:`MIN_REACH_M`,
    :data:`BODY_HALF_SPAN_M`]; both :data:`BODY_HALF_SPAN_M` when ``result`` (a
    ``PredictionResult``) is None or has no finite keypoints (a custom provider's)."""
    try:
        points = result.posterior.mode().keypoints3d[0].double().cpu().numpy()  # type: ignore[attr-defined]
    except (AttributeError, TypeError, IndexError, ValueError):
        return BODY_HALF_SPAN_M, BODY_HALF_SPAN_M
    x = np.asarray(points, dtype=np.float64).reshape(-1, 3)[:, 0]
    if x.size == 0 or not np.all(np.isfinite(x)):
        return BODY_HALF_SPAN_M, BODY_HALF_SPAN_M
    left, right = -float(np.min(x)) + HAND_ROOM_M, float(np.max(x)) + HAND_ROOM_M
    return (
        float(np.clip(left, MIN_REACH_M, BODY_HALF_SPAN_M)),
        float(np.clip(right, MIN_REACH_M, BODY_HALF_SPAN_M)),
    )


def column_layout(result: object) -> ColumnLayout:
    """The columns spaced by ``result``'s reach (:func:`body_extent`): the photo ends the
    body's left reach plus :data:`COLUMN_GAP_M` from its centre, and the uncertainty body
    stands one right reach plus one left reach plus :data:`COLUMN_GAP_M` from the most likely
    body; never wider than :data:`DEFAULT_LAYOUT`."""
    left, right = body_extent(result)
    return ColumnLayout(
        photo_gap=min(left + COLUMN_GAP_M, DEFAULT_LAYOUT.photo_gap),
        step=min(left + right + COLUMN_GAP_M, DEFAULT_LAYOUT.step),
    )
