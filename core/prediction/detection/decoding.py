"""Decoding BlazePose's raw outputs: detector boxes and keypoints, weighted non-maximum
suppression, and the landmark model's 33 landmarks with their visibility.

Units: the detector works in its 224-pixel input, and this module returns its results
normalised to that input (``[0, 1]``, x right, y down, 0 at the input's left/top edge). The
landmark model returns landmarks in its 256-pixel crop; they are normalised to the crop the same
way. :mod:`hkpd.prediction.detection.warp` maps either back to the photo.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

DETECTOR_KEYPOINTS = 4
"""Keypoints per detection: hip centre, a point on the full-body circle, shoulder centre and a
point on the upper-body circle."""

SCORE_CLIP = 100.0
"""Raw detector scores are clipped to ±this before the sigmoid."""

NMS_IOU_THRESHOLD = 0.3
"""Detections overlapping the best remaining one by more than this IoU are merged into it."""

LANDMARKS = 39
"""Landmarks of the landmark model: BlazePose's 33 plus 6 auxiliary ones (for tracking)."""

VALUES_PER_LANDMARK = 5
"""``x, y, z, visibility logit, presence logit`` per landmark (x, y, z in crop pixels)."""

HEATMAP_KERNEL = 7
"""Side of the heatmap window whose confidence-weighted mean refines a landmark."""

HEATMAP_MIN_CONFIDENCE = 0.5
"""A landmark is refined only when its window's highest heatmap confidence reaches this."""


def sigmoid(values: np.ndarray) -> np.ndarray:
    """Logistic function, elementwise (float64; written with tanh, which cannot overflow)."""
    return 0.5 * (1.0 + np.tanh(0.5 * np.asarray(values, np.float64)))


@dataclass(frozen=True)
class Detections:
    """Person detections, normalised to the detector's input.

    Attributes:
        boxes: ``(N, 4)`` float64 ``(x0, y0, x1, y1)``.
        keypoints: ``(N, 4, 2)`` float64 ``(x, y)`` of the :data:`DETECTOR_KEYPOINTS`.
        scores: ``(N,)`` float64 in [0, 1], sorted from best to worst after :func:`weighted_nms`.
    """

    boxes: np.ndarray
    keypoints: np.ndarray
    scores: np.ndarray

    def __len__(self) -> int:
        return int(self.scores.shape[0])


def decode_detections(
    raw_boxes: np.ndarray,
    raw_scores: np.ndarray,
    anchors: np.ndarray,
    min_score: float,
    input_size: int,
) -> Detections:
    """Detector outputs to boxes and keypoints of the anchors that score at least ``min_score``.

    Each anchor's 12 numbers are, in input pixels relative to the anchor centre: the box centre
    ``(dx, dy)``, its size ``(w, h)``, then ``(dx, dy)`` of each of the four keypoints.

    Args:
        raw_boxes: ``(N, 12)`` regression outputs.
        raw_scores: ``(N,)`` or ``(N, 1)`` score logits.
        anchors: ``(N, 2)`` anchor centres, normalised (:func:`ssd_anchor_centres`).
        min_score: sigmoid score threshold.
        input_size: side of the detector's input, pixels (224).

    Returns:
        The kept :class:`Detections`, in anchor order.
    """
    scores = sigmoid(
        np.clip(np.asarray(raw_scores, np.float64).reshape(-1), -SCORE_CLIP, SCORE_CLIP)
    )
    kept = np.flatnonzero(scores >= min_score)
    values = np.asarray(raw_boxes, np.float64)[kept] / input_size
    centres = anchors[kept]
    box_centre = values[:, 0:2] + centres
    half = values[:, 2:4] / 2
    boxes = np.concatenate([box_centre - half, box_centre + half], axis=1)
    keypoints = values[:, 4:].reshape(-1, DETECTOR_KEYPOINTS, 2) + centres[:, None, :]
    return Detections(boxes, keypoints, scores[kept])


def box_iou(box: np.ndarray, others: np.ndarray) -> np.ndarray:
    """IoU of one ``(4,)`` box ``(x0, y0, x1, y1)`` with each of ``(N, 4)`` boxes -> ``(N,)``."""
    low = np.maximum(box[:2], others[:, :2])
    high = np.minimum(box[2:], others[:, 2:])
    overlap = np.prod(np.clip(high - low, 0.0, None), axis=1)
    area = np.prod(box[2:] - box[:2])
    areas = np.prod(others[:, 2:] - others[:, :2], axis=1)
    union = area + areas - overlap
    return np.where(union > 0, overlap / np.where(union > 0, union, 1.0), 0.0)


def weighted_nms(detections: Detections, iou_threshold: float = NMS_IOU_THRESHOLD) -> Detections:
    """Weighted non-maximum suppression: one detection per cluster of overlapping ones.

    Repeatedly takes the best remaining detection and every remaining one whose IoU with it
    exceeds ``iou_threshold``; they become one detection whose box and keypoints are their
    score-weighted mean and whose score is the best one's. Raw anchors jitter by a few pixels,
    so averaging them is steadier than keeping only the best.

    Returns:
        The merged :class:`Detections`, best score first.
    """
    order = np.argsort(-detections.scores, kind="stable")
    boxes, keypoints, scores = (
        detections.boxes[order],
        detections.keypoints[order],
        detections.scores[order],
    )
    remaining = np.arange(len(scores))
    merged_boxes, merged_keypoints, merged_scores = [], [], []
    while remaining.size:
        best = remaining[0]
        cluster_mask = box_iou(boxes[best], boxes[remaining]) > iou_threshold
        cluster_mask[0] = True
        cluster = remaining[cluster_mask]
        weights = scores[cluster] / scores[cluster].sum()
        merged_boxes.append(weights @ boxes[cluster])
        merged_keypoints.append(np.einsum("n,nkc->kc", weights, keypoints[cluster]))
        merged_scores.append(scores[best])
        remaining = remaining[~cluster_mask]
    if not merged_scores:
        return Detections(np.zeros((0, 4)), np.zeros((0, DETECTOR_KEYPOINTS, 2)), np.zeros(0))
    return Detections(np.array(merged_boxes), np.array(merged_keypoints), np.array(merged_scores))


@dataclass(frozen=True)
class CropLandmarks:
    """Landmarks in the landmark model's crop.

    Attributes:
        points: ``(39, 2)`` float64 ``(x, y)`` normalised to the crop (0 at its left/top edge).
        visibility: ``(39,)`` float64 in [0, 1], sigmoid of the visibility logit.
        presence: ``(39,)`` float64 in [0, 1], sigmoid of the presence logit.
    """

    points: np.ndarray
    visibility: np.ndarray
    presence: np.ndarray


def decode_landmarks(raw: np.ndarray, heatmap: np.ndarray | None, crop_size: int) -> CropLandmarks:
    """The landmark model's outputs to normalised crop landmarks.

    Args:
        raw: ``(195,)`` (or any shape with 195 values): 39 × ``(x, y, z, visibility logit,
            presence logit)``, x and y in crop pixels.
        heatmap: ``(h, w, 39)`` heatmap logits (64 × 64), or None to skip the refinement.
        crop_size: side of the model's input crop, pixels (256).

    Returns:
        :class:`CropLandmarks` (positions refined by :func:`refine_from_heatmap`).
    """
    values = np.asarray(raw, np.float64).reshape(LANDMARKS, VALUES_PER_LANDMARK)
    points = values[:, :2] / crop_size
    if heatmap is not None:
        points = refine_from_heatmap(points, heatmap)
    return CropLandmarks(points, sigmoid(values[:, 3]), sigmoid(values[:, 4]))


def refine_from_heatmap(
    points: np.ndarray,
    heatmap: np.ndarray,
    kernel: int = HEATMAP_KERNEL,
    min_confidence: float = HEATMAP_MIN_CONFIDENCE,
) -> np.ndarray:
    """Move each landmark to the confidence-weighted mean cell of its heatmap window.

    The window is ``kernel × kernel`` heatmap cells around the cell the landmark falls in
    (clipped to the heatmap); confidences are the sigmoid of the heatmap logits. A landmark
    outside the heatmap, or whose window's best confidence is below ``min_confidence``, keeps
    its regressed position.

    Args:
        points: ``(L, 2)`` normalised ``(x, y)``.
        heatmap: ``(h, w, L)`` logits.

    Returns:
        ``(L, 2)`` refined normalised positions (a new array).
    """
    rows, cols = heatmap.shape[:2]
    half = (kernel - 1) // 2
    refined = np.array(points, np.float64)
    for index, (x, y) in enumerate(points):
        col, row = int(x * cols), int(y * rows)
        if not (0 <= col < cols and 0 <= row < rows):
            continue
        r0, r1 = max(row - half, 0), min(row + half + 1, rows)
        c0, c1 = max(col - half, 0), min(col + half + 1, cols)
        confidence = sigmoid(heatmap[r0:r1, c0:c1, index])
        total = confidence.sum()
        if confidence.max() < min_confidence or total <= 0:
            continue
        grid_rows, grid_cols = np.mgrid[r0:r1, c0:c1]
        refined[index] = (
            (confidence * grid_cols).sum() / total / cols,
            (confidence * grid_rows).sum() / total / rows,
        )
    return refined
