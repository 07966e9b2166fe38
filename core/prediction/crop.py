"""The square crop the network sees, and the exact map between crop and photo pixels.

A :class:`CropTransform` is a square box in original-photo pixels (``centre``, ``side``) that is
resampled to a ``size`` x ``size`` crop (:data:`hkpd.camera_conventions.CROP_SIZE`, 256). With
pixel centres at integer coordinates (:mod:`hkpd.camera_conventions`), the box's edges
``centre ± side / 2`` land on the crop's outer edges ``-0.5`` and ``size - 0.5``::

    crop = (image - centre + side / 2) * size / side - 0.5
    image = (crop + 0.5) * side / size + centre - side / 2

so crop NDC (``hkpd.camera_conventions.pixels_to_ndc``) is ``(image - centre) * 2 / side``.

Box placement (:meth:`CropTransform.from_keypoints`) is the synthetic training data's rule,
:func:`hkpd.proxy.square_box_around_keypoints`: a square centred on the bounding box of the
keypoints, of side ``hkpd.proxy.CROP_MARGIN`` (1.2, STRAPS-style) times its longer extent.
Training boxes surround all 17 keypoints, occluded ones included (then scale by a random 0.8-1.2),
so by default every keypoint the detector returns places the box, whatever its confidence
(BlazePose's confidence is a visibility, not a localisation quality); points outside the photo
are pulled onto its border first. COCO keypoints end at the eyes/ears and ankles; the 10 % extra
on each side covers the top of the head and the feet of a standing person (checked on the
shipped body model in the tests).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
import torch

from hkpd.camera_conventions import CROP_SIZE
from hkpd.prediction.image_input import LoadedImage
from hkpd.prediction.pixel_maps import Points, scale_and_shift
from hkpd.proxy import CROP_MARGIN, square_box_around_keypoints

BOX_CONFIDENCE_THRESHOLD = 0.0
"""Default: keypoints below this confidence do not place the box. 0 uses them all, like the
synthetic training crops; raise it for detectors whose low-confidence points are unreliable."""

MIN_BOX_SIDE = 8.0
"""Smallest box side, in original pixels; a smaller box means the keypoints are degenerate."""

_ANTIALIAS_FROM = 1.5
"""Box-to-crop shrink factor above which the image is area-averaged before the affine warp."""


@dataclass(frozen=True)
class CropTransform:
    """A square box in original-photo pixels and its ``size`` x ``size`` crop.

    Attributes:
        centre: ``(u, v)`` box centre, original-photo pixels.
        side: box side, original-photo pixels (> 0).
        size: crop side in pixels.
    """

    centre: tuple[float, float]
    side: float
    size: int = CROP_SIZE

    def __post_init__(self) -> None:
        if not (np.isfinite(self.side) and self.side > 0):
            raise ValueError(f"crop side must be a positive number of pixels, got {self.side}")
        if not np.isfinite(self.centre).all() or len(self.centre) != 2:
            raise ValueError(f"crop centre must be two finite numbers, got {self.centre}")
        if self.size < 1:
            raise ValueError(f"crop size must be positive, got {self.size}")

    @classmethod
    def from_keypoints(
        cls,
        keypoints: np.ndarray,
        confidences: np.ndarray | None = None,
        image_size: tuple[int, int] | None = None,
        *,
        margin: float = CROP_MARGIN,
        min_confidence: float = BOX_CONFIDENCE_THRESHOLD,
        size: int = CROP_SIZE,
    ) -> CropTransform:
        """Square box around the keypoints (the training crops' rule, see the module docstring).

        Args:
            keypoints: ``(J, 2)`` original-photo pixels (e.g. ``KeypointDetection.keypoints``).
            confidences: ``(J,)``; None counts every keypoint.
            image_size: ``(width, height)`` of the photo; when given, keypoints outside it are
                moved onto its border, so the box does not reach into what the photo does not
                show (a person cut off at the knees fills the crop down to the photo's edge).
            margin: side = ``margin * max(width, height)`` of the keypoints' bounding box.
            min_confidence: keypoints below it are ignored.
            size: crop side in pixels.

        Raises:
            ValueError: fewer than two confident keypoints, or they span less than
                :data:`MIN_BOX_SIDE` pixels.
        """
        points = np.asarray(keypoints, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != 2:
            raise ValueError(f"keypoints must be (J, 2), got shape {points.shape}")
        keep = np.isfinite(points).all(1)
        if confidences is not None:
            conf = np.asarray(confidences, dtype=np.float64)
            if conf.shape != points.shape[:1]:
                raise ValueError(
                    f"confidences must be ({points.shape[0]},) to match the keypoints, got "
                    f"{conf.shape}"
                )
            keep &= conf >= min_confidence
        if keep.sum() < 2:
            raise ValueError(
                f"only {int(keep.sum())} keypoint(s) have confidence >= {min_confidence}; a crop "
                "box needs at least two. The person is barely visible: use a clearer photo or "
                "give the person's box (--bbox)"
            )
        if image_size is not None:
            width, height = image_size
            points = np.clip(points, -0.5, [width - 0.5, height - 0.5])
        centre, side = square_box_around_keypoints(
            torch.from_numpy(np.nan_to_num(points))[None], torch.from_numpy(keep)[None], margin
        )
        return cls._square(centre[0].numpy(), float(side[0]), size)

    @classmethod
    def from_bbox(
        cls,
        bbox: Sequence[float] | np.ndarray,
        *,
        margin: float = CROP_MARGIN,
        size: int = CROP_SIZE,
    ) -> CropTransform:
        """Square box centred on ``bbox = (x0, y0, x1, y1)`` (original pixels), side
        ``margin * max(x1 - x0, y1 - y0)``.

        Raises:
            ValueError: not four finite numbers with ``x1 > x0`` and ``y1 > y0``.
        """
        box = np.asarray(bbox, dtype=np.float64)
        if box.shape != (4,) or not np.isfinite(box).all() or box[2] <= box[0] or box[3] <= box[1]:
            raise ValueError(
                f"bbox must be (x0, y0, x1, y1) with x1 > x0 and y1 > y0, got {bbox!r}"
            )
        return cls._square((box[:2] + box[2:]) / 2, margin * float((box[2:] - box[:2]).max()), size)

    @classmethod
    def _square(cls, centre: np.ndarray, side: float, size: int) -> CropTransform:
        if side < MIN_BOX_SIDE:
            raise ValueError(
                f"the crop box would be only {side:.1f} pixels wide (minimum {MIN_BOX_SIDE}); the "
                "keypoints or bbox cover almost nothing of the photo"
            )
        return cls((float(centre[0]), float(centre[1])), float(side), size)

    @property
    def pixels_per_unit(self) -> float:
        """Crop pixels per original-photo pixel, ``size / side``."""
        return self.size / self.side

    @property
    def box(self) -> tuple[float, float, float, float]:
        """``(x0, y0, x1, y1)`` outer edges of the box in original-photo pixel coordinates."""
        half = self.side / 2
        return (self.centre[0] - half, self.centre[1] - half,
                self.centre[0] + half, self.centre[1] + half)  # fmt: skip

    def image_to_crop(self, points: Points) -> Points:
        """``(..., 2)`` original-photo pixels to crop pixels (numpy or torch, kind kept)."""
        scale = self.pixels_per_unit
        shift = [(self.side / 2 - c) * scale - 0.5 for c in self.centre]
        return scale_and_shift(points, (scale, scale), shift)

    def crop_to_image(self, points: Points) -> Points:
        """``(..., 2)`` crop pixels to original-photo pixels; the exact inverse of
        :meth:`image_to_crop`."""
        scale = self.side / self.size
        shift = [0.5 * scale + c - self.side / 2 for c in self.centre]
        return scale_and_shift(points, (scale, scale), shift)

    def affine_matrix(self) -> np.ndarray:
        """``(2, 3)`` float64 matrix ``A`` with ``crop = A @ [u, v, 1]`` (OpenCV's convention)."""
        scale = self.pixels_per_unit
        shift = [(self.side / 2 - c) * scale - 0.5 for c in self.centre]
        return np.array([[scale, 0.0, shift[0]], [0.0, scale, shift[1]]])

    def crop_image(
        self, image: np.ndarray | LoadedImage, image_scale: tuple[float, float] = (1.0, 1.0)
    ) -> np.ndarray:
        """Resample the box into a ``(size, size, C)`` crop; outside the photo is black.

        Bilinear interpolation; when the box is more than 1.5x larger than the crop, the part of
        the image under the box is first area-averaged down to about crop resolution so the
        crop is not aliased (Canny edges of an aliased crop would be noise).

        Args:
            image: ``(H, W, C)`` or ``(H, W)`` uint8 pixels. Either the original photo, or a
                downscaled working copy (``LoadedImage.pixels``) with ``image_scale`` set; or
                a :class:`LoadedImage`, whose own scale is then used.
            image_scale: per-axis ``image / original`` size ratio (``LoadedImage.scale``);
                ignored for a :class:`LoadedImage`.

        Returns:
            ``(size, size, C)`` (or ``(size, size)``) of ``image``'s dtype.
        """
        if isinstance(image, LoadedImage):
            image, image_scale = image.pixels, image.scale
        if image.ndim not in (2, 3) or image.shape[0] == 0 or image.shape[1] == 0:
            raise ValueError(f"expected an (H, W[, C]) image, got shape {image.shape}")
        # Affine from `image` pixels to crop pixels: original = (p + 0.5) / s - 0.5, then crop.
        sx, sy = image_scale
        to_original = np.array(
            [[1 / sx, 0, 0.5 / sx - 0.5], [0, 1 / sy, 0.5 / sy - 0.5], [0, 0, 1]]
        )
        matrix = self.affine_matrix() @ to_original
        shrink = 1.0 / min(matrix[0, 0], matrix[1, 1])
        if shrink > _ANTIALIAS_FROM:
            image, matrix = _area_downscale_region(image, matrix, self.size, shrink)
        border = 0 if image.ndim == 2 else (0,) * image.shape[2]
        return cv2.warpAffine(
            image,
            matrix,
            (self.size, self.size),
            flags=cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=border,
        )


def _area_downscale_region(
    image: np.ndarray, matrix: np.ndarray, size: int, shrink: float
) -> tuple[np.ndarray, np.ndarray]:
    """Cut the image region under the crop, area-average it by ``shrink``, and return it with
    the affine from its pixels to crop pixels."""
    inverse = cv2.invertAffineTransform(matrix)
    corners = np.array([[-0.5, -0.5], [size - 0.5, size - 0.5]]) @ inverse[:, :2].T + inverse[:, 2]
    height, width = image.shape[:2]
    x0, y0 = np.clip(np.floor(corners.min(0)) - 1, 0, [width, height]).astype(int)
    x1, y1 = np.clip(np.ceil(corners.max(0)) + 2, 0, [width, height]).astype(int)
    if x1 - x0 < 2 or y1 - y0 < 2:  # the box misses the image: the crop is all border
        return image, matrix
    region = image[y0:y1, x0:x1]
    new_size = (max(1, round((x1 - x0) / shrink)), max(1, round((y1 - y0) / shrink)))
    small = cv2.resize(region, new_size, interpolation=cv2.INTER_AREA)
    rx, ry = new_size[0] / (x1 - x0), new_size[1] / (y1 - y0)
    # small pixel q -> region pixel (q + 0.5) / r - 0.5 -> image pixel + (x0, y0).
    from_small = np.array(
        [[1 / rx, 0, 0.5 / rx - 0.5 + x0], [0, 1 / ry, 0.5 / ry - 0.5 + y0], [0, 0, 1]]
    )
    return small, matrix @ from_small
