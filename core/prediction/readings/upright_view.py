"""A second view of the crop, turned so that the person's torso points up.

The network was trained almost only on upright people; a person leaning or lying is better
read from a copy of the crop rotated upright. :class:`UprightView` is the similarity map from
the crop to that copy (rotation about the crop centre, then a square box around the rotated
keypoints by the usual crop rule), and maps the network's answer on the copy back to the
crop's frame, exactly:

    n' = k Rot n + o            (crop NDC n -> upright-copy NDC n')
    R_g = Rot3ᵀ R_g',   s = s' / k,   t = Rotᵀ (t' - o / s')

where ``Rot3`` is ``Rot`` as a rotation about the camera's optical axis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
import torch

from hkpd.prediction.crop import CropTransform

SHOULDERS = (5, 6)
HIPS = (11, 12)
HEAD = (0, 1, 2, 3, 4)
KNEES = (13, 14)


def torso_tilt(keypoints: np.ndarray, observed: np.ndarray) -> float | None:
    """Angle (radians, clockwise on screen) of the hip-to-shoulder direction from straight up.

    The direction is the mean of the same-side hip-to-shoulder vectors that are observed (a
    person seen from the side often shows only one side). Without a whole side, it runs from
    the observed hips (else knees) to the observed shoulders (else head keypoints).

    Args:
        keypoints: ``(17, 2)`` COCO keypoints in pixels (v down).
        observed: ``(17,)`` bool.

    Returns:
        The angle in ``(-π, π]``, or None when neither the torso nor a stand-in for it is
        observed.
    """
    points = np.asarray(keypoints, dtype=np.float64)
    seen = np.asarray(observed, dtype=bool)
    sides = [(s, h) for s, h in zip(SHOULDERS, HIPS, strict=True) if seen[s] and seen[h]]
    if sides:
        direction = np.mean([points[s] - points[h] for s, h in sides], axis=0)
    else:
        upper = _observed_mean(points, seen, SHOULDERS)
        if upper is None:
            upper = _observed_mean(points, seen, HEAD)
        lower = _observed_mean(points, seen, HIPS)
        if lower is None:
            lower = _observed_mean(points, seen, KNEES)
        if upper is None or lower is None:
            return None
        direction = upper - lower
    if not np.isfinite(direction).all() or np.hypot(*direction) < 1e-6:
        return None
    return math.atan2(direction[0], -direction[1])


def _observed_mean(
    points: np.ndarray, seen: np.ndarray, indices: tuple[int, ...]
) -> np.ndarray | None:
    """``(2,)`` mean of the observed ``indices``, or None when none is observed."""
    chosen = [i for i in indices if seen[i]]
    return points[chosen].mean(0) if chosen else None


@dataclass(frozen=True)
class UprightView:
    """The crop -> upright-copy similarity (see the module docstring).

    Attributes:
        rotation: ``(2, 2)`` float64, turns the torso upright (pixel axes, v down).
        box: the square box around the rotated keypoints, in rotated crop pixels.
        size: crop side in pixels.
    """

    rotation: np.ndarray
    box: CropTransform
    size: int

    @classmethod
    def from_tilt(
        cls,
        tilt: float,
        keypoints_crop: np.ndarray,
        size: int,
        observed: np.ndarray | None = None,
    ) -> UprightView:
        """The view that undoes ``tilt`` (from :func:`torso_tilt`) for a ``size`` crop; its box
        frames the ``observed`` keypoints (``(17,)`` bool; None: all of them)."""
        cosine, sine = math.cos(tilt), math.sin(tilt)
        # A clockwise tilt is undone by turning counter-clockwise on screen (v points down).
        rotation = np.array([[cosine, sine], [-sine, cosine]])
        centre = (size - 1) / 2.0
        rotated = (np.asarray(keypoints_crop, dtype=np.float64) - centre) @ rotation.T + centre
        weights = None if observed is None else np.asarray(observed, dtype=np.float64)
        box = CropTransform.from_keypoints(rotated, weights, size=size, min_confidence=0.5)
        return cls(rotation, box, size)

    @property
    def tilt(self) -> float:
        """The lean this view undoes, radians clockwise on screen (as :func:`torso_tilt`)."""
        return math.atan2(float(self.rotation[0, 1]), float(self.rotation[0, 0]))

    @property
    def scale(self) -> float:
        """``k``: upright-copy NDC per crop NDC."""
        return self.size / self.box.side

    @property
    def offset(self) -> np.ndarray:
        """``o``: ``(2,)`` NDC offset of the copy."""
        centre = (self.size - 1) / 2.0
        return 2.0 * (centre - np.asarray(self.box.centre)) / self.box.side

    def _pixel_affine(self) -> np.ndarray:
        """``(2, 3)`` map from crop pixels to upright-copy pixels."""
        centre = (self.size - 1) / 2.0
        linear = self.rotation * self.scale
        shift = (
            centre
            - self.rotation @ np.full(2, centre)
            - np.asarray(self.box.centre)
            + self.box.side / 2
        ) * self.scale - 0.5
        return np.concatenate((linear, shift[:, None]), axis=1)

    def warp(self, crop_rgb: np.ndarray) -> np.ndarray:
        """The upright copy of a ``(S, S, C)`` crop image (outside the crop: black)."""
        return cv2.warpAffine(
            crop_rgb,
            self._pixel_affine(),
            (self.size, self.size),
            flags=cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_CONSTANT,
        )

    def warp_planes(self, image_planes: np.ndarray) -> np.ndarray:
        """The upright copy of ``(C, S, S)`` uint8 image planes (:mod:`hkpd.proxy`'s compact
        image proxy), nearest pixel so that edges and silhouettes stay binary; outside the
        crop: 0."""
        return np.stack(
            [
                cv2.warpAffine(
                    np.ascontiguousarray(plane),
                    self._pixel_affine(),
                    (self.size, self.size),
                    flags=cv2.INTER_NEAREST,
                    borderMode=cv2.BORDER_CONSTANT,
                )
                for plane in image_planes
            ]
        )

    def points(self, keypoints_crop: np.ndarray) -> np.ndarray:
        """``(..., 2)`` crop pixels to upright-copy pixels."""
        affine = self._pixel_affine()
        return np.asarray(keypoints_crop, dtype=np.float64) @ affine[:, :2].T + affine[:, 2]

    def to_crop_frame(
        self, global_orient: torch.Tensor, camera: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """The network's ``(3, 3)`` global rotation and ``(3,)`` camera on the copy, in the
        crop's frame."""
        dtype = global_orient.dtype
        rotation = torch.as_tensor(self.rotation, dtype=dtype)
        rotation3 = torch.eye(3, dtype=dtype)
        rotation3[:2, :2] = rotation
        offset = torch.as_tensor(self.offset, dtype=dtype)
        scale, translation = camera[0], camera[1:]
        orient = rotation3.T @ global_orient
        shift = rotation.T @ (translation - offset / scale)
        return orient, torch.cat(((scale / self.scale).reshape(1), shift))
