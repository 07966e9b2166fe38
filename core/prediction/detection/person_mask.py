"""BlazePose's person segmentation: a probability mask over the landmark model's region.

The landmark model's segmentation head gives ``M × M`` logits (``M = 256``) over the same
rotated square crop the landmarks were found in; pixel ``(col, row)`` of that crop shows the
photo at ``crop_matrix(region, M) @ [col, row, 1]``
(:func:`hkpd.prediction.detection.warp.crop_matrix`). :class:`PersonMask` keeps the
probabilities (the sigmoid of the logits) in the crop's own pixels together with that affine
map, composed with the working-image → original-photo scaling, so that the mask can be
resampled once, exactly, into any other frame: the original photo (:meth:`PersonMask.in_photo`)
or the network's crop (:meth:`PersonMask.in_frame`). Outside the landmark region the
probability is 0 (the region is 1.25× the detector's full-body circle: the person is inside).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

MASK_THRESHOLD = 0.5
"""Probability above which a pixel belongs to the person."""


@dataclass(frozen=True, eq=False)
class PersonMask:
    """One person's segmentation probabilities and where they lie in the original photo.

    Attributes:
        probability: ``(M, M)`` float32 in [0, 1], the landmark crop's pixels (row, col)
            (any ``(h, w)`` grid works; BlazePose's is 256 × 256).
        to_photo: ``(2, 3)`` float64 affine map, ``[u, v] = to_photo @ [col, row, 1]``: mask
            pixel centre -> original-photo pixel (pixel centres at integers).
        image_size: ``(width, height)`` of the original photo, pixels.
    """

    probability: np.ndarray
    to_photo: np.ndarray
    image_size: tuple[int, int]

    def __repr__(self) -> str:
        """One line: the grid, the photo's size and how much of the grid is the person (never
        the probabilities)."""
        rows, cols = np.shape(self.probability)[:2]
        person = float(np.mean(np.asarray(self.probability) >= 0.5)) if rows * cols else 0.0
        return (
            f"PersonMask({rows}x{cols} grid, {person:.0%} person (p >= 0.5), photo "
            "{}x{})".format(*self.image_size)
        )

    def moved(self, matrix: np.ndarray, image_size: tuple[int, int]) -> PersonMask:
        """The same mask in another photo frame: ``matrix`` ``(2, 3)`` maps this mask's photo
        pixels to the new frame's (e.g. working image -> original photo)."""
        to_photo = (_square(matrix) @ _square(self.to_photo))[:2]
        return PersonMask(self.probability, to_photo, image_size)

    def in_frame(self, photo_to_frame: np.ndarray, size: tuple[int, int]) -> np.ndarray:
        """The probabilities resampled (bilinearly, once) into another frame of the photo.

        Args:
            photo_to_frame: ``(2, 3)`` affine, original-photo pixels -> frame pixels (e.g.
                :meth:`hkpd.prediction.crop.CropTransform.affine_matrix`).
            size: ``(width, height)`` of the frame, pixels.

        Returns:
            ``(height, width)`` float32 in [0, 1]; 0 outside the landmark region.
        """
        matrix = (_square(photo_to_frame) @ _square(self.to_photo))[:2]
        warped = cv2.warpAffine(
            self.probability.astype(np.float32),
            matrix,
            (int(size[0]), int(size[1])),
            flags=cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=0.0,
        )
        return np.clip(warped, 0.0, 1.0)

    def in_photo(self) -> np.ndarray:
        """``(H, W)`` float32 in [0, 1]: the probabilities in original-photo pixels."""
        return self.in_frame(np.eye(2, 3), self.image_size)

    def box(self) -> np.ndarray | None:
        """``(4,)`` ``(x0, y0, x1, y1)`` photo-pixel box (unclipped) of the mask pixel centres
        above :data:`MASK_THRESHOLD`, or None when the mask is empty."""
        above = self.probability > MASK_THRESHOLD
        rows = np.flatnonzero(above.any(axis=1))
        if rows.size == 0:
            return None
        # An affine map's extremes over the pixels lie at each row's first and last pixel.
        first = above[rows].argmax(axis=1)
        last = above.shape[1] - 1 - above[rows, ::-1].argmax(axis=1)
        cols, rows = np.concatenate([first, last]), np.concatenate([rows, rows])
        centres = np.stack([cols, rows, np.ones_like(cols)], axis=1).astype(np.float64)
        points = centres @ self.to_photo.T
        return np.concatenate([points.min(0), points.max(0)])


def _square(matrix: np.ndarray) -> np.ndarray:
    """``(3, 3)`` homogeneous form of a ``(2, 3)`` affine map."""
    return np.vstack([np.asarray(matrix, np.float64), [0.0, 0.0, 1.0]])
