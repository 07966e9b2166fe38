"""Where the photo sits in the 3D scene, and how screen drags map onto its pixels.

World frame of the explorer: y up, the viewer on +z looking towards -z. The photo is a plane
node whose LOCAL frame has +x to the right and +y DOWN (viser draws images that way), i.e. the
node is turned by a half turn about x. The body is shown in the same kind of node, so body
coordinates (OpenCV: x right, y down, z away) go into the scene unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import viser.transforms

HALF_TURN_ABOUT_X = (0.0, 1.0, 0.0, 0.0)
"""``wxyz`` of the photo and body nodes: OpenCV axes inside a y-up world."""


@dataclass(frozen=True)
class PhotoPlacement:
    """The photo's rectangle in the world.

    Attributes:
        width_px, height_px: photo size in pixels.
        centre: ``(3,)`` world position of the photo centre.
        height_m: rendered height in scene units (metres); width follows the aspect ratio.
    """

    width_px: int
    height_px: int
    centre: tuple[float, float, float]
    height_m: float

    @property
    def width_m(self) -> float:
        return self.height_m * self.width_px / self.height_px

    @property
    def metres_per_pixel(self) -> float:
        return self.height_m / self.height_px

    def pixels_to_local(self, pixels: np.ndarray) -> np.ndarray:
        """``(..., 2)`` pixel-edge coordinates to ``(..., 2)`` photo-node local x, y (metres)."""
        pixels = np.asarray(pixels, dtype=np.float64)
        size = np.array([self.width_px, self.height_px], dtype=np.float64)
        return (pixels - size / 2.0) * self.metres_per_pixel

    def on_photo(self, pixels: np.ndarray) -> np.ndarray:
        """``(N, 2)`` photo pixels (pixel-centre coordinates) -> ``(N,)`` bool: on the photo
        (what is drawn over the photo is drawn only there, never below or beside it)."""
        points = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        inside = (points >= -0.5).all(axis=1) & np.isfinite(points).all(axis=1)
        return (
            inside & (points[:, 0] <= self.width_px - 0.5) & (points[:, 1] <= self.height_px - 0.5)
        )

    def clip_image(
        self, rgba: np.ndarray, box: tuple[float, float, float, float]
    ) -> tuple[np.ndarray, tuple[float, float, float, float]] | None:
        """The part of an image ``(S, S, 4)`` pasted over photo box ``box`` (photo pixels,
        corners) that lies on the photo, and that part's box; None when none does."""
        x0, y0, x1, y1 = box
        rows, cols = rgba.shape[:2]
        per_col, per_row = cols / max(x1 - x0, 1e-9), rows / max(y1 - y0, 1e-9)
        left, top = (
            max(0, int(np.ceil(-x0 * per_col - 1e-9))),
            max(0, int(np.ceil(-y0 * per_row - 1e-9))),
        )
        right = min(cols, int(np.floor((self.width_px - x0) * per_col + 1e-9)))
        bottom = min(rows, int(np.floor((self.height_px - y0) * per_row + 1e-9)))
        if right <= left or bottom <= top:
            return None
        kept = (
            x0 + left / per_col,
            y0 + top / per_row,
            x0 + right / per_col,
            y0 + bottom / per_row,
        )
        return rgba[top:bottom, left:right], kept

    def world_to_pixels(self, points: np.ndarray) -> np.ndarray:
        """``(..., 3)`` world points ON the photo plane to ``(..., 2)`` pixel coordinates."""
        points = np.asarray(points, dtype=np.float64)
        local_x = points[..., 0] - self.centre[0]
        local_y = -(points[..., 1] - self.centre[1])  # world y up, photo y down
        size = np.array([self.width_px, self.height_px], dtype=np.float64)
        local = np.stack([local_x, local_y], axis=-1)
        return local / self.metres_per_pixel + size / 2.0


def screen_ray(
    screen_xy: tuple[float, float],
    camera_position: np.ndarray,
    camera_rotation: np.ndarray,
    fov_y: float,
    aspect: float,
) -> tuple[np.ndarray, np.ndarray]:
    """The world ray through a screen point of a viser (OpenCV-style) camera.

    Args:
        screen_xy: ``(u, v)`` in [0, 1], (0, 0) top left (viser's ``screen_pos``).
        camera_position: ``(3,)`` world position.
        camera_rotation: ``(3, 3)`` camera-to-world rotation (columns: right, down, forward).
        fov_y: vertical field of view, radians.
        aspect: width / height of the canvas.

    Returns:
        origin ``(3,)`` and unit direction ``(3,)``.
    """
    half = np.tan(fov_y / 2.0)
    direction_cam = np.array(
        [(2.0 * screen_xy[0] - 1.0) * half * aspect, (2.0 * screen_xy[1] - 1.0) * half, 1.0]
    )
    direction = np.asarray(camera_rotation, dtype=np.float64) @ direction_cam
    return np.asarray(camera_position, dtype=np.float64), direction / np.linalg.norm(direction)


def ray_hits_photo(
    origin: np.ndarray, direction: np.ndarray, placement: PhotoPlacement
) -> np.ndarray | None:
    """Pixel coordinates ``(2,)`` where a ray meets the photo's (infinite) plane, or None.

    The plane is ``z = centre.z``; rays parallel to it or pointing away give None. The point
    may lie outside the photo: callers clamp.
    """
    if abs(direction[2]) < 1e-9:
        return None
    distance = (placement.centre[2] - origin[2]) / direction[2]
    if distance <= 0:
        return None
    return placement.world_to_pixels(origin + distance * direction)


def screen_rect_to_box(
    screen_min: tuple[float, float],
    screen_max: tuple[float, float],
    camera_position: np.ndarray,
    camera_rotation: np.ndarray,
    fov_y: float,
    aspect: float,
    placement: PhotoPlacement,
) -> tuple[float, float, float, float] | None:
    """The pixel box covered by a screen rectangle dragged over the photo.

    The four screen corners are cast onto the photo plane; the box is their bounding box (exact
    when the photo faces the camera, a slight over-cover when seen at an angle). Not clamped.

    Returns:
        ``(x0, y0, x1, y1)`` photo pixels, or None if a corner misses the plane.
    """
    corners = [
        (screen_min[0], screen_min[1]),
        (screen_max[0], screen_min[1]),
        (screen_min[0], screen_max[1]),
        (screen_max[0], screen_max[1]),
    ]
    hits = []
    for corner in corners:
        origin, direction = screen_ray(corner, camera_position, camera_rotation, fov_y, aspect)
        hit = ray_hits_photo(origin, direction, placement)
        if hit is None:
            return None
        hits.append(hit)
    points = np.stack(hits)
    x0, y0 = points.min(axis=0)
    x1, y1 = points.max(axis=0)
    return (float(x0), float(y0), float(x1), float(y1))


def quaternion_to_matrix(wxyz: np.ndarray) -> np.ndarray:
    """``(3, 3)`` rotation matrix of a quaternion ``(w, x, y, z)`` (normalised first)."""
    quaternion = np.asarray(wxyz, dtype=np.float64)
    return viser.transforms.SO3(quaternion / np.linalg.norm(quaternion)).as_matrix()
