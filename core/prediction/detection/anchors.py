"""Anchor centres of BlazePose's person detector (single-shot detector, 224×224 input).

The detector predicts, for every anchor, a box and four keypoints relative to the anchor's
centre. Its anchors follow the usual SSD layout: feature maps at strides 8, 16, 32, 32, 32 (the
three stride-32 layers share one 7×7 map); each layer puts two anchors on every cell of its map
(one per aspect ratio, here only 1.0, plus one of interpolated scale). With fixed-size anchors
only the centres matter: cell ``(row, col)`` of a ``rows × cols`` map has its anchors at
``((col + 0.5) / cols, (row + 0.5) / rows)`` in input-normalised units.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

DETECTOR_INPUT_SIZE = 224
"""Side of the detector's square input, pixels."""

DETECTOR_STRIDES = (8, 16, 32, 32, 32)
"""Feature-map stride of each anchor layer, input pixels."""

ANCHORS_PER_LAYER_AND_CELL = 2
"""One anchor per aspect ratio (only 1.0) plus one of interpolated scale."""


def ssd_anchor_centres(
    input_size: int = DETECTOR_INPUT_SIZE,
    strides: Sequence[int] = DETECTOR_STRIDES,
    anchors_per_layer: int = ANCHORS_PER_LAYER_AND_CELL,
    offset: float = 0.5,
) -> np.ndarray:
    """Centres of all anchors, in the detector's output order.

    Consecutive layers with the same stride share a feature map: their anchors are interleaved
    per cell. Cells run row by row, columns within a row.

    Args:
        input_size: side of the square input, pixels.
        strides: stride of each layer.
        anchors_per_layer: anchors each layer places on a cell.
        offset: position of the anchor inside its cell, in cells.

    Returns:
        ``(N, 2)`` float64 ``(x, y)`` in [0, 1] of the input (N = 2254 for BlazePose).
    """
    centres = []
    layer = 0
    while layer < len(strides):
        stride = strides[layer]
        shared = 1
        while layer + shared < len(strides) and strides[layer + shared] == stride:
            shared += 1
        cells = math.ceil(input_size / stride)
        grid = (np.arange(cells, dtype=np.float64) + offset) / cells
        ys, xs = np.meshgrid(grid, grid, indexing="ij")
        per_cell = np.stack([xs.ravel(), ys.ravel()], axis=1)
        centres.append(np.repeat(per_cell, shared * anchors_per_layer, axis=0))
        layer += shared
    return np.concatenate(centres)
