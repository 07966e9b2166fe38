"""Backgrounds for synthetic renders: procedural clutter, or random crops of the user's photos.

The paper pastes its bodies on LSUN scenes, so the edge detector sees background clutter (edges
that do not belong to the person) as it does on real photos. We cannot ship LSUN; by default we
draw clutter: a colour gradient with smooth low-frequency shading, then 4-14 random filled or
outlined rectangles (some rotated), ellipses, polygons and lines of random colours, sometimes
a patch of fine texture, and a random blur (sigma 0-1.5 px) so that edge strengths vary. With a
folder of photos (jpg/png, searched recursively), each background is instead a random square crop
(a random 50-100% of the shorter side), resized to the output size and randomly mirrored.

Drawing uses OpenCV on the CPU (a few microseconds per shape); all random choices come from the
given torch generator, so a seeded generator reproduces the same backgrounds.
"""

from __future__ import annotations

from collections import OrderedDict
from pathlib import Path

import cv2
import numpy as np
import torch

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png")
CACHE_SIZE = 64
"""Decoded photos kept in memory in folder mode."""
MAX_DECODED_SIDE_FACTOR = 3
"""Photos are downscaled on load so their shorter side is at most this many output sizes."""


class BackgroundSource:
    """Random backgrounds.

    Args:
        folder: directory searched recursively for ``.jpg``/``.jpeg``/``.png`` photos, loaded
            lazily (the ``CACHE_SIZE`` most recent are kept decoded); None draws procedural
            clutter.

    Raises:
        FileNotFoundError: ``folder`` does not exist or is not a directory.
        ValueError: ``folder`` holds no image files.
    """

    def __init__(self, folder: Path | str | None = None) -> None:
        self.folder = None if folder is None else Path(folder)
        self.files: list[Path] = []
        self._cache: OrderedDict[Path, np.ndarray] = OrderedDict()
        if self.folder is not None:
            if not self.folder.is_dir():
                raise FileNotFoundError(f"background folder {self.folder} is not a directory")
            self.files = sorted(
                path
                for path in self.folder.rglob("*")
                if path.suffix.lower() in IMAGE_SUFFIXES and path.is_file()
            )
            if not self.files:
                raise ValueError(
                    f"background folder {self.folder} contains no images "
                    f"({', '.join(IMAGE_SUFFIXES)}, searched recursively); add photos or use "
                    "BackgroundSource() for procedural backgrounds"
                )

    def sample(
        self,
        count: int,
        generator: torch.Generator | None = None,
        image_size: int = 256,
        device: torch.device | str = "cpu",
    ) -> torch.Tensor:
        """Random backgrounds.

        Args:
            count: number of images B.
            generator: torch random generator (any device; None: the global one).
            image_size: side of the square images in pixels.
            device: where the returned tensor lives.

        Returns:
            ``(B, 3, H, W)`` float32 RGB in [0, 1].
        """
        rng = _TorchRandom(generator)
        images = np.empty((count, image_size, image_size, 3), dtype=np.float32)
        for index in range(count):
            if self.folder is None:
                images[index] = draw_clutter(image_size, rng)
            else:
                images[index] = self._crop(image_size, rng)
        return torch.from_numpy(images).permute(0, 3, 1, 2).contiguous().to(device)

    def _crop(self, size: int, rng: _TorchRandom) -> np.ndarray:
        path = self.files[rng.integer(len(self.files))]
        photo = self._load(path, size)
        height, width = photo.shape[:2]
        side = max(1, round(min(height, width) * rng.uniform(0.5, 1.0)))
        top = rng.integer(height - side + 1)
        left = rng.integer(width - side + 1)
        crop = photo[top : top + side, left : left + side]
        interpolation = cv2.INTER_AREA if side > size else cv2.INTER_LINEAR
        crop = cv2.resize(crop, (size, size), interpolation=interpolation)
        if rng.uniform(0.0, 1.0) < 0.5:
            crop = crop[:, ::-1]
        return crop

    def _load(self, path: Path, size: int) -> np.ndarray:
        if path in self._cache:
            self._cache.move_to_end(path)
            return self._cache[path]
        bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
        if bgr is None:
            raise ValueError(f"cannot decode background image {path}")
        shorter = min(bgr.shape[:2])
        limit = MAX_DECODED_SIDE_FACTOR * size
        if shorter > limit:
            scale = limit / shorter
            bgr = cv2.resize(bgr, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
        photo = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB).astype(np.float32) / 255.0
        self._cache[path] = photo
        if len(self._cache) > CACHE_SIZE:
            self._cache.popitem(last=False)
        return photo


class _TorchRandom:
    """Scalar random numbers drawn in blocks from a torch generator (on its own device)."""

    BLOCK = 4096

    def __init__(self, generator: torch.Generator | None) -> None:
        self.generator = generator
        self.device = generator.device if generator is not None else torch.device("cpu")
        self._values: list[float] = []

    def uniform(self, low: float, high: float) -> float:
        if not self._values:
            block = torch.rand(self.BLOCK, generator=self.generator, device=self.device)
            self._values = block.tolist()[::-1]
        return low + (high - low) * self._values.pop()

    def integer(self, high: int) -> int:
        """Uniform integer in ``[0, high)``."""
        return min(int(self.uniform(0.0, high)), high - 1)

    def colour(self) -> tuple[float, float, float]:
        return (self.uniform(0.0, 1.0), self.uniform(0.0, 1.0), self.uniform(0.0, 1.0))


def draw_clutter(size: int, rng: _TorchRandom) -> np.ndarray:
    """One procedural background: ``(size, size, 3)`` float32 RGB in [0, 1] (module docstring)."""
    image = _gradient(size, rng)
    for _ in range(4 + rng.integer(11)):
        kind = rng.integer(6)
        colour = _muted_colour(rng)
        filled = rng.uniform(0.0, 1.0) < 0.7
        thickness = -1 if filled else 1 + rng.integer(4)
        centre = (rng.integer(size), rng.integer(size))
        if kind == 0:  # axis-aligned rectangle
            corner = (rng.integer(size), rng.integer(size))
            cv2.rectangle(image, centre, corner, colour, thickness)
        elif kind == 1:  # rotated rectangle
            box = ((centre[0], centre[1]), (rng.uniform(8, size * 0.6), rng.uniform(8, size * 0.6)))
            points = cv2.boxPoints((*box, rng.uniform(0, 180))).astype(np.int32)
            if filled:
                cv2.fillConvexPoly(image, points, colour)
            else:
                cv2.polylines(image, [points], True, colour, thickness)
        elif kind == 2:  # ellipse
            axes = (1 + rng.integer(size // 3), 1 + rng.integer(size // 3))
            cv2.ellipse(image, centre, axes, rng.uniform(0, 180), 0, 360, colour, thickness)
        elif kind == 3:  # polygon
            points = np.array(
                [[rng.integer(size), rng.integer(size)] for _ in range(3 + rng.integer(4))],
                dtype=np.int32,
            )
            if filled:
                cv2.fillPoly(image, [points], colour)
            else:
                cv2.polylines(image, [points], True, colour, thickness)
        elif kind == 4:  # long line
            end = (rng.integer(size), rng.integer(size))
            cv2.line(image, centre, end, colour, 1 + rng.integer(6))
        else:  # patch of fine texture (stripes)
            _texture_patch(image, size, rng)
    sigma = rng.uniform(0.0, 1.5)
    if sigma > 0.3:
        image = cv2.GaussianBlur(image, (0, 0), sigma)
    return np.clip(image, 0.0, 1.0)


def _gradient(size: int, rng: _TorchRandom) -> np.ndarray:
    """Smooth colour field: a coarse grid of related random colours, bicubically upsampled."""
    grid = 2 + rng.integer(4)
    base = np.array(_muted_colour(rng), dtype=np.float32)
    # Mostly brightness variation, with a little hue drift.
    coarse = np.array(
        [
            [brightness + rng.uniform(-0.05, 0.05) for _ in range(3)]
            for brightness in (rng.uniform(-0.3, 0.3) for _ in range(grid * grid))
        ],
        dtype=np.float32,
    ).reshape(grid, grid, 3)
    field = cv2.resize(base + coarse, (size, size), interpolation=cv2.INTER_CUBIC)
    return np.ascontiguousarray(field, dtype=np.float32)


def _muted_colour(rng: _TorchRandom) -> tuple[float, float, float]:
    """A random colour pulled towards its own grey by a random amount (photos are rarely vivid)."""
    red, green, blue = rng.colour()
    grey = (red + green + blue) / 3.0
    keep = rng.uniform(0.2, 1.0)
    return (grey + keep * (red - grey), grey + keep * (green - grey), grey + keep * (blue - grey))


def _texture_patch(image: np.ndarray, size: int, rng: _TorchRandom) -> None:
    """Fill a random rectangle with fine two-colour stripes (in place)."""
    x0, y0 = rng.integer(size), rng.integer(size)
    x1 = min(size, x0 + 8 + rng.integer(size // 2))
    y1 = min(size, y0 + 8 + rng.integer(size // 2))
    period = rng.uniform(2.5, 8.0)
    angle = rng.uniform(0.0, np.pi)
    ys, xs = np.mgrid[y0:y1, x0:x1].astype(np.float32)
    wave = np.sin((np.cos(angle) * xs + np.sin(angle) * ys) * (2 * np.pi / period)) > 0
    first = np.array(_muted_colour(rng), dtype=np.float32)
    second = np.array(_muted_colour(rng), dtype=np.float32)
    image[y0:y1, x0:x1] = np.where(wave[..., None], first, second)
