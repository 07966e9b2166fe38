"""The colour scale that paints per-vertex uncertainty onto meshes, renders and colour bars.

One fixed, stated scale keeps pictures of different photos comparable: uncertainty (the mean
distance of sampled vertices from their mean, metres, :func:`hkpd.uncertainty.
vertex_uncertainty`) from :data:`UNCERTAINTY_MIN_M` (0 cm) to :data:`UNCERTAINTY_MAX_M`
(10 cm) is mapped linearly onto a viridis-like ramp (dark purple -> blue -> green -> yellow);
values above the top are drawn in the top colour. The ramp is a piecewise-linear interpolation
through nine anchor colours sampled from matplotlib's ``viridis`` (perceptually uniform, readable
in greyscale and by colour-blind viewers), so matplotlib is not needed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

UNCERTAINTY_MIN_M = 0.0
"""Uncertainty drawn in the bottom colour of the scale, metres."""

UNCERTAINTY_MAX_M = 0.10
"""Uncertainty drawn in the top colour of the scale (and everything above it), metres."""

VIRIDIS_ANCHORS = np.array(
    [
        [68, 1, 84], [71, 44, 122], [59, 81, 139], [44, 113, 142], [33, 144, 141],
        [39, 173, 129], [92, 200, 99], [170, 220, 50], [253, 231, 37],
    ],
    dtype=np.float64,
) / 255.0  # fmt: skip
"""``(9, 3)`` RGB in [0, 1] of viridis at 0, 1/8, ..., 1."""


@dataclass(frozen=True)
class UncertaintyColourScale:
    """A linear map from uncertainty in metres to an RGB colour on the viridis-like ramp.

    Attributes:
        minimum_m: uncertainty at the bottom of the scale, metres.
        maximum_m: uncertainty at the top of the scale, metres (> ``minimum_m``).
        name: the ramp's name, for JSON summaries and captions.
    """

    minimum_m: float = UNCERTAINTY_MIN_M
    maximum_m: float = UNCERTAINTY_MAX_M
    name: str = "viridis"

    def __post_init__(self) -> None:
        if not (np.isfinite(self.minimum_m) and np.isfinite(self.maximum_m)):
            raise ValueError("the colour scale's limits must be finite numbers of metres")
        if self.maximum_m <= self.minimum_m:
            raise ValueError(
                f"the colour scale needs maximum > minimum, got {self.minimum_m}..{self.maximum_m}"
            )

    def fraction(self, uncertainty_m: np.ndarray) -> np.ndarray:
        """Position on the scale in [0, 1] of ``(...)`` uncertainties in metres (clipped)."""
        values = np.asarray(uncertainty_m, dtype=np.float64)
        span = self.maximum_m - self.minimum_m
        return np.clip((np.nan_to_num(values) - self.minimum_m) / span, 0.0, 1.0)

    def colours(self, uncertainty_m: np.ndarray) -> np.ndarray:
        """``(..., 3)`` float64 RGB in [0, 1] of ``(...)`` uncertainties in metres."""
        return ramp_colours(self.fraction(uncertainty_m))

    def colours_uint8(self, uncertainty_m: np.ndarray) -> np.ndarray:
        """``(..., 3)`` uint8 RGB of ``(...)`` uncertainties in metres."""
        return np.round(self.colours(uncertainty_m) * 255.0).astype(np.uint8)

    def ticks_cm(self, step_cm: float = 2.0) -> list[float]:
        """Tick values in centimetres from the bottom to the top of the scale."""
        low, high = self.minimum_m * 100.0, self.maximum_m * 100.0
        count = int(np.floor((high - low) / step_cm + 1e-9))
        return [round(low + k * step_cm, 6) for k in range(count + 1)]

    @property
    def label(self) -> str:
        """The scale in words, as every colour bar of hkpd names it: ``"linear 0-10 cm"``
        (the explorer's default is ``"log 1-32 cm"``: a class compares colours only between
        pictures whose bars say the same)."""
        return f"linear {self.minimum_m * 100:g}-{self.maximum_m * 100:g} cm"

    def describe(self) -> dict[str, object]:
        """The scale as plain data (for the JSON summary)."""
        return {
            "colour_map": self.name,
            "minimum_m": self.minimum_m,
            "maximum_m": self.maximum_m,
            "mapping": "linear in metres between minimum and maximum; values above maximum "
            "take the top colour",
        }


def ramp_colours(fraction: np.ndarray) -> np.ndarray:
    """``(..., 3)`` float64 RGB in [0, 1] of positions ``(...)`` in [0, 1] along the ramp."""
    position = np.clip(np.asarray(fraction, dtype=np.float64), 0.0, 1.0)
    scaled = position * (len(VIRIDIS_ANCHORS) - 1)
    lower = np.minimum(np.floor(scaled).astype(np.int64), len(VIRIDIS_ANCHORS) - 2)
    weight = (scaled - lower)[..., None]
    return VIRIDIS_ANCHORS[lower] * (1.0 - weight) + VIRIDIS_ANCHORS[lower + 1] * weight


def vertex_to_face_values(values: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """``(F,)`` mean over each face's three corners of per-vertex ``values`` ``(V,)``."""
    return np.asarray(values, dtype=np.float64)[np.asarray(faces)].mean(axis=1)
