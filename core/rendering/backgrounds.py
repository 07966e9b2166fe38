"""Backgrounds for synthetic renders: procedural clutter, or random crops of the user's photos.

The paper pastes its bodies on LSUN scenes, so the edge detector sees background clutter (edges
that do not belong to the person) as it does on real photos. We cannot ship LSUN; by default we
draw clutter: a smooth colour field (a coarse random grid, upsampled), then 4-14 random filled or
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
        pool_size: procedural mode only. 0 (default): draw every background afresh (~1.5 ms of
            CPU each). N > 0: keep N drawn backgrounds (each 1.25x the output size) and serve
            random crops of them, randomly mirrored, replacing
            ``refresh_fraction`` of the requested count by fresh drawings per call: several
            times cheaper, at the price of backgrounds recurring (in new crops) for a while.
        refresh_fraction: share of each call's count drawn anew into the pool.

    Raises:
        FileNotFoundError: ``folder`` does not exist or is not a directory.
        ValueError: ``folder`` holds no image files.
    """

    def __init__(
        self,
        folder: Path | str | None = None,
        pool_size: int = 0,
        refresh_fraction: float = 0.25,
    ) -> None:
        if pool_size < 0 or not 0.0 <= refresh_fraction <= 1.0:
            raise ValueError(
                f"pool_size must be >= 0 and refresh_fraction in [0, 1], got {pool_size}, "
                f"{refresh_fraction}"
            )
        self.pool_size = pool_size
        self.refresh_fraction = refresh_fraction
        self._pool: list[np.ndarray] = []
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
            ``(B, 3, H, W)`` float32 RGB in [0, 1], stored channels-last (call
            ``.contiguous()`` if a consumer needs the plain layout).
        """
        rng = _TorchRandom(generator)
        images = np.empty((count, image_size, image_size, 3), dtype=np.float32)
        for index in range(count):
            if self.folder is not None:
                images[index] = self._crop(image_size, rng)
            elif self.pool_size == 0:
                images[index] = draw_clutter(image_size, rng)
        if self.folder is None and self.pool_size > 0:
            self._fill_from_pool(images, rng)
        # A channels-last (B, 3, H, W) view: transposing the memory costs more than drawing.
        return torch.from_numpy(images).permute(0, 3, 1, 2).to(device)

    def _fill_from_pool(self, images: np.ndarray, rng: _TorchRandom) -> None:
        """Refresh part of the pool, then fill ``images (B, S, S, 3)`` with random crops of it."""
        count, size = images.shape[0], images.shape[1]
        canvas = (size * 5) // 4
        if self._pool and self._pool[0].shape[0] != canvas:
            self._pool = []  # a new output size: start again
        fresh = max(1, round(self.refresh_fraction * count)) if count else 0
        for _ in range(fresh):
            drawing = draw_clutter(canvas, rng)
            if len(self._pool) < self.pool_size:
                self._pool.append(drawing)
            else:
                self._pool[rng.integer(self.pool_size)] = drawing
        while len(self._pool) < min(self.pool_size, count):
            self._pool.append(draw_clutter(canvas, rng))
        for index in range(count):
            source = self._pool[rng.integer(len(self._pool))]
            top, left = rng.integer(canvas - size + 1), rng.integer(canvas - size + 1)
            crop = source[top : top + size, left : left + size]
            if rng.uniform(0.0, 1.0) < 0.5:
                cv2.flip(crop, 1, dst=images[index])
            else:
                images[index] = crop

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
        taps = 2 * int(np.ceil(2.0 * sigma)) + 1  # ±2 sigma is plenty for a soft edge
        image = cv2.GaussianBlur(image, (taps, taps), sigma)
    return image  # every colour drawn is in [0, 1], and blurring keeps it there


def _gradient(size: int, rng: _TorchRandom) -> np.ndarray:
    """Smooth colour field: a coarse grid of related random colours, upsampled."""
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
    # Bilinear upsampling: smooth, never outside [0, 1], and ~10x cheaper than bicubic.
    coarse = np.clip(base + coarse, 0.0, 1.0)
    return cv2.resize(coarse, (size, size), interpolation=cv2.INTER_LINEAR)


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
    xs = np.arange(x0, x1, dtype=np.float32) * np.float32(np.cos(angle) / period)
    ys = np.arange(y0, y1, dtype=np.float32) * np.float32(np.sin(angle) / period)
    wave = np.floor(xs[None, :] + ys[:, None]).astype(np.int32) % 2 == 0
    first = np.array(_muted_colour(rng), dtype=np.float32)
    second = np.array(_muted_colour(rng), dtype=np.float32)
    image[y0:y1, x0:x1] = np.where(wave[..., None], first, second)
