"""The COCO-17 keypoint convention shared by the body model's regressor, the detector, the
proxy heatmaps, visibility and the pictures."""

from __future__ import annotations

COCO17_NAMES: tuple[str, ...] = (
    "nose", "left_eye", "right_eye", "left_ear", "right_ear", "left_shoulder", "right_shoulder",
    "left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_hip", "right_hip",
    "left_knee", "right_knee", "left_ankle", "right_ankle",
)  # fmt: skip
"""The COCO-17 keypoint names, in COCO order (also ``BodyModel`` keypoint order)."""

COCO17_LEFT_RIGHT_PAIRS: tuple[tuple[int, int], ...] = (
    (5, 6), (7, 8), (9, 10), (11, 12), (13, 14), (15, 16),
)  # fmt: skip
"""Left/right pairs of limb keypoints: shoulders, elbows, wrists, hips, knees, ankles."""

COCO17_FACE_LEFT_RIGHT_PAIRS: tuple[tuple[int, int], ...] = ((1, 2), (3, 4))
"""Left/right pairs of face keypoints: eyes, ears."""


def _mirror_order() -> tuple[int, ...]:
    order = list(range(len(COCO17_NAMES)))
    for left, right in (*COCO17_FACE_LEFT_RIGHT_PAIRS, *COCO17_LEFT_RIGHT_PAIRS):
        order[left], order[right] = right, left
    return tuple(order)


COCO17_MIRROR_ORDER: tuple[int, ...] = _mirror_order()
"""``COCO17_MIRROR_ORDER[k]``: the keypoint that keypoint k becomes in a left-right mirror image
(every left keypoint and its right partner, face included, trade places; the nose stays)."""

COCO17_LIMBS: tuple[tuple[int, int], ...] = (
    (0, 1), (0, 2), (1, 3), (2, 4), (5, 6), (5, 7), (7, 9), (6, 8), (8, 10), (5, 11), (6, 12),
    (11, 12), (11, 13), (13, 15), (12, 14), (14, 16),
)  # fmt: skip
"""Pairs of COCO-17 keypoints joined by a skeleton line in pictures."""
