"""Colours for per-vertex uncertainty in the explorer, and the colour-bar legend.

The colours are the library's one uncertainty ramp
(:mod:`hkpd.prediction.exports.uncertainty_colours`, viridis-like, the same as
``hkpd-predict``'s pictures), so a screenshot and an exported render of the same prediction
agree. The scale is FIXED (0 .. ``max_cm``) rather than stretched to each
prediction, so that hiding a limb visibly turns it warmer instead of silently rescaling
everything; the explorer's slider moves the top.
"""

from __future__ import annotations

import cv2
import numpy as np

from hkpd.prediction.exports.uncertainty_colours import (
    UNCERTAINTY_MAX_M,
    UncertaintyColourScale,
)

DEFAULT_MAX_CM = UNCERTAINTY_MAX_M * 100.0
"""Default top of the uncertainty colour scale, centimetres (``hkpd-predict``'s too)."""


def uncertainty_colours(uncertainty_m: np.ndarray, max_cm: float = DEFAULT_MAX_CM) -> np.ndarray:
    """Map uncertainties to RGB colours.

    Args:
        uncertainty_m: ``(V,)`` per-vertex uncertainty in metres (>= 0).
        max_cm: value (centimetres) that gets the top colour; larger values saturate.

    Returns:
        ``(V, 3)`` uint8 RGB.
    """
    if max_cm <= 0:
        raise ValueError(f"max_cm must be positive, got {max_cm}")
    return UncertaintyColourScale(maximum_m=max_cm / 100.0).colours_uint8(uncertainty_m)


def legend_image(max_cm: float = DEFAULT_MAX_CM, width: int = 320, height: int = 64) -> np.ndarray:
    """A horizontal colour bar with tick labels in centimetres.

    Returns:
        ``(height, width, 3)`` uint8 RGB on a white background.
    """
    image = np.full((height, width, 3), 255, dtype=np.uint8)
    font = 0.42 * height / 64
    thickness = max(1, round(height / 64))
    (unit_width, _), _ = cv2.getTextSize("cm", cv2.FONT_HERSHEY_SIMPLEX, font, thickness)
    left, right = round(14 * height / 64), width - unit_width - round(24 * height / 64)
    top, bottom = round(6 * height / 64), height // 2
    ramp = np.linspace(0.0, max_cm / 100.0, right - left)
    image[top:bottom, left:right] = uncertainty_colours(ramp, max_cm)[None]
    cv2.rectangle(image, (left - 1, top - 1), (right, bottom), (90, 90, 90), 1)
    ticks = _tick_values(max_cm)
    for value in ticks:
        x = left + round(value / max_cm * (right - left - 1))
        cv2.line(image, (x, bottom), (x, bottom + 4), (60, 60, 60), 1)
        text = f"{value:g}"
        (w, h), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, font, thickness)
        baseline = bottom + round(6 * height / 64) + h
        cv2.putText(image, text, (x - w // 2, baseline), cv2.FONT_HERSHEY_SIMPLEX, font,
                    (40, 40, 40), thickness, cv2.LINE_AA)  # fmt: skip
    unit_x = x + w // 2 + round(5 * height / 64)
    cv2.putText(image, "cm", (unit_x, baseline), cv2.FONT_HERSHEY_SIMPLEX, font, (40, 40, 40),
                thickness, cv2.LINE_AA)  # fmt: skip
    return image


def _tick_values(max_cm: float) -> list[float]:
    """About five round tick values from 0 to ``max_cm``."""
    raw = max_cm / 5.0
    magnitude = 10.0 ** np.floor(np.log10(raw))
    step = min((m * magnitude for m in (1.0, 2.0, 2.5, 5.0, 10.0)), key=lambda s: abs(s - raw))
    return [float(v) for v in np.arange(0.0, max_cm + 1e-9, step)]
