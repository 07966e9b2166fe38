"""Square, possibly rotated regions of a photo and the model-input crops cut from them.

Both BlazePose models look at a square crop of the photo: the detector at the whole photo
letterboxed into 224×224, the landmark model at a rotated square around one person, 256×256.
A :class:`Region` is that square in photo pixels; it maps normalised crop coordinates
(``[0, 1]``, 0 at the crop's left/top edge, as the models' outputs are decoded) to photo pixels
and back, and :func:`crop` cuts the model input from the photo.

Photo coordinates are ``(u, v)`` pixels with pixel centres at integers. As in MediaPipe, the crop
samples the photo half a pixel right of and below the exact position (it takes coordinates
measured from the photo's edge as if they were measured from the first pixel's centre); hkpd
keeps that so that its keypoints match the legacy solution's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

HALF_PIXEL = 0.5
"""Where MediaPipe samples, relative to the exact position, in photo pixels (see above)."""


@dataclass(frozen=True)
class Region:
    """A square in the photo, rotated about its centre.

    Attributes:
        centre: ``(2,)`` ``(u, v)`` photo pixels (pixel centres at integers).
        size: side, photo pixels.
        angle: rotation, radians: the crop's "up" points along ``(sin a, -cos a)`` in the photo
            (0: upright; π/2: the crop's up is the photo's right).
    """

    centre: np.ndarray
    size: float
    angle: float

    def rotation(self) -> np.ndarray:
        """``(2, 2)`` matrix turning crop directions into photo directions."""
        cos, sin = math.cos(self.angle), math.sin(self.angle)
        return np.array([[cos, -sin], [sin, cos]])

    def to_photo(self, points: np.ndarray) -> np.ndarray:
        """``(..., 2)`` normalised crop coordinates -> photo pixels."""
        offsets = (np.asarray(points, np.float64) - 0.5) * self.size
        return offsets @ self.rotation().T + self.centre

    def from_photo(self, points: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`to_photo`: photo pixels -> normalised crop coordinates."""
        offsets = (np.asarray(points, np.float64) - self.centre) @ self.rotation()
        return offsets / self.size + 0.5


def letterbox_region(width: int, height: int) -> Region:
    """The upright square centred on a ``width × height`` photo whose side is the longer side:
    the whole photo, padded on the short axis."""
    return Region(
        centre=np.array([width / 2 - 0.5, height / 2 - 0.5]),
        size=float(max(width, height)),
        angle=0.0,
    )


def person_region(hip_centre: np.ndarray, body_point: np.ndarray, scale: float) -> Region:
    """The landmark model's region from the detector's hip centre and full-body circle point.

    The square is centred on the hip centre, its side is ``scale`` × the circle's diameter, and
    it is rotated so that the direction from the hip centre to the circle point (the detector's
    estimate of "towards the head") is the crop's up.

    Args:
        hip_centre, body_point: ``(2,)`` photo pixels.
        scale: side / diameter (1.25 for BlazePose).
    """
    delta = np.asarray(body_point, np.float64) - hip_centre
    angle = math.pi / 2 - math.atan2(-delta[1], delta[0])
    angle = (angle + math.pi) % (2 * math.pi) - math.pi
    return Region(np.array(hip_centre, np.float64), 2 * float(np.hypot(*delta)) * scale, angle)


def crop_matrix(region: Region, output_size: int) -> np.ndarray:
    """``(2, 3)`` affine map from crop pixels (centres at integers) to the photo positions they
    sample (OpenCV's convention, with :data:`HALF_PIXEL`), for ``cv2.WARP_INVERSE_MAP``."""
    linear = region.rotation() * (region.size / output_size)
    origin = region.to_photo(np.zeros(2)) + HALF_PIXEL
    return np.concatenate([linear, origin[:, None]], axis=1)


def crop(pixels: np.ndarray, region: Region, output_size: int, replicate: bool) -> np.ndarray:
    """Cut ``region`` out of the photo, bilinearly resampled to ``output_size``².

    Args:
        pixels: ``(H, W, 3)`` uint8 RGB photo.
        region: the square to cut.
        output_size: side of the crop, pixels.
        replicate: fill parts outside the photo with the nearest edge pixel (as BlazePose's
            landmark model expects) instead of black (its detector's letterbox).

    Returns:
        ``(output_size, output_size, 3)`` uint8.
    """
    return cv2.warpAffine(
        pixels,
        crop_matrix(region, output_size),
        (output_size, output_size),
        flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
        borderMode=cv2.BORDER_REPLICATE if replicate else cv2.BORDER_CONSTANT,
        borderValue=(0, 0, 0),
    )
