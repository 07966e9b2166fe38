"""Colours for per-vertex uncertainty in the explorer, and the colour-bar legend.

Three colourings of the uncertainty body (:data:`COLOURINGS`, chosen in the Samples folder):

* ``"log"`` (default): uncertainty in centimetres on a LOG scale from :data:`LOG_BOTTOM_CM`
  to :data:`LOG_TOP_CM`. The chain ends of the shipped model (forearms, feet: 15-23 cm on the
  shipped photo) and the torso (2-4 cm) both stay inside the scale, so nothing saturates, and
  the scale is fixed: hiding a limb visibly turns it warmer instead of rescaling everything.
* ``"linear"``: 0 .. ``max_cm`` centimetres, linear (``hkpd-predict``'s scale; values above
  the top saturate); the Samples folder's slider moves the top.
* ``"change"``: each vertex's uncertainty divided by its uncertainty in the *baseline*
  posterior (the same photo without occluders and with default concentrations), on a diverging
  blue-grey-red map, log scale from 1/:data:`CHANGE_MAX_RATIO` to :data:`CHANGE_MAX_RATIO`.

The absolute colourings use the library's one uncertainty ramp
(:mod:`hkpd.prediction.exports.uncertainty_colours`, viridis-like, the same as
``hkpd-predict``'s pictures). Every legend says what is shown and in which unit.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from hkpd.prediction.exports.uncertainty_colours import (
    UNCERTAINTY_MAX_M,
    UncertaintyColourScale,
    ramp_colours,
)

DEFAULT_MAX_CM = UNCERTAINTY_MAX_M * 100.0
"""Default top of the linear uncertainty colour scale, centimetres (``hkpd-predict``'s too)."""

LOG_BOTTOM_CM = 1.0
LOG_TOP_CM = 32.0
"""Ends of the log scale, centimetres (values outside take the end colours)."""
LOG_LABEL = f"log {LOG_BOTTOM_CM:g}-{LOG_TOP_CM:g} cm"
"""The log scale in words, as its colour bar says (``hkpd-predict``'s overview says
:attr:`~hkpd.prediction.exports.uncertainty_colours.UncertaintyColourScale.label`,
"linear 0-10 cm", the explorer's *linear* colouring at its default top)."""

CHANGE_MAX_RATIO = 3.0
"""The change colouring's reddest ratio (and 1/this the bluest)."""

COLOURINGS: dict[str, str] = {
    "log": "Uncertainty, log scale (cm)",
    "linear": "Uncertainty, linear 0 .. top (cm)",
    "change": "Change vs. no occluders, default concentrations (×)",
}
"""The colourings of the uncertainty body: key -> the Samples folder's label."""

DIVERGING_ANCHORS = np.array(
    [[33, 102, 172], [103, 169, 207], [209, 229, 240], [225, 225, 225], [253, 219, 199],
     [239, 138, 98], [178, 24, 43]],
    dtype=np.float64,
) / 255.0  # fmt: skip
"""``(7, 3)`` RGB in [0, 1] of the diverging map at 0, 1/6, ..., 1 (blue, light grey at the
centre, red; after ColorBrewer's RdBu, readable by red-green colour-blind viewers)."""


def uncertainty_colours(uncertainty_m: np.ndarray, max_cm: float = DEFAULT_MAX_CM) -> np.ndarray:
    """Map uncertainties to RGB colours, linear 0 .. ``max_cm``.

    Args:
        uncertainty_m: ``(V,)`` per-vertex uncertainty in metres (>= 0).
        max_cm: value (centimetres) that gets the top colour; larger values saturate.

    Returns:
        ``(V, 3)`` uint8 RGB.
    """
    if max_cm <= 0:
        raise ValueError(f"max_cm must be positive, got {max_cm}")
    return UncertaintyColourScale(maximum_m=max_cm / 100.0).colours_uint8(uncertainty_m)


def log_uncertainty_colours(uncertainty_m: np.ndarray) -> np.ndarray:
    """``(V,)`` metres to ``(V, 3)`` uint8 RGB on the log scale :data:`LOG_BOTTOM_CM` ..
    :data:`LOG_TOP_CM`."""
    return _to_uint8(ramp_colours(_log_fraction(np.asarray(uncertainty_m) * 100.0)))


def change_colours(ratio: np.ndarray) -> np.ndarray:
    """``(V,)`` uncertainty ratios (current / baseline, > 0) to ``(V, 3)`` uint8 RGB on the
    diverging map: 1 light grey, larger red, smaller blue, saturating at
    :data:`CHANGE_MAX_RATIO` and its inverse."""
    values = np.nan_to_num(np.asarray(ratio, dtype=np.float64), nan=1.0, posinf=CHANGE_MAX_RATIO)
    fraction = 0.5 + 0.5 * np.log(np.maximum(values, 1e-6)) / np.log(CHANGE_MAX_RATIO)
    return _to_uint8(_diverging(fraction))


@dataclass(frozen=True)
class HeatmapScale:
    """One colouring of the uncertainty body (see the module docstring).

    Attributes:
        kind: a key of :data:`COLOURINGS`.
        max_cm: top of the ``"linear"`` scale, centimetres.
    """

    kind: str = "log"
    max_cm: float = DEFAULT_MAX_CM

    def __post_init__(self) -> None:
        if self.kind not in COLOURINGS:
            raise ValueError(f"unknown colouring {self.kind!r}; use one of {list(COLOURINGS)}")
        if not self.max_cm > 0:
            raise ValueError(f"max_cm must be positive, got {self.max_cm}")

    def colours(self, values: np.ndarray) -> np.ndarray:
        """``(V, 3)`` uint8 RGB of ``(V,)`` values: metres for the absolute kinds, ratios for
        ``"change"``."""
        if self.kind == "change":
            return change_colours(values)
        if self.kind == "log":
            return log_uncertainty_colours(values)
        return uncertainty_colours(values, self.max_cm)

    def legend(self, width: int = 320, height: int = 64) -> np.ndarray:
        """The colour bar of this colouring (``(height, width, 3)`` uint8), titled."""
        if self.kind == "change":
            return change_legend_image(width, height)
        if self.kind == "log":
            return log_legend_image(width, height)
        return legend_image(self.max_cm, width, height)


def legend_image(max_cm: float = DEFAULT_MAX_CM, width: int = 320, height: int = 64) -> np.ndarray:
    """The linear colour bar 0 .. ``max_cm`` with tick labels in centimetres.

    Returns:
        ``(height, width, 3)`` uint8 RGB on a white background.
    """
    ticks = [(value / max_cm, f"{value:g}") for value in _tick_values(max_cm)]
    scale = UncertaintyColourScale(maximum_m=max_cm / 100.0)
    title = f"Uncertainty over samples, {scale.label} (saturates above)"
    return _bar_image(ramp_colours, ticks, title, "cm", width, height)


def log_legend_image(width: int = 320, height: int = 64) -> np.ndarray:
    """The log colour bar :data:`LOG_BOTTOM_CM` .. :data:`LOG_TOP_CM` (ticks at powers of 2)."""
    values = 2.0 ** np.arange(np.log2(LOG_BOTTOM_CM), np.log2(LOG_TOP_CM) + 1e-9)
    ticks = [(float(_log_fraction(v)), f"{v:g}") for v in values]
    return _bar_image(ramp_colours, ticks, f"Uncertainty over samples, {LOG_LABEL}", "cm",
                      width, height)  # fmt: skip


def change_legend_image(
    width: int = 320,
    height: int = 64,
    title: str = "Uncertainty ÷ no occluders, default concentrations",
) -> np.ndarray:
    """The diverging colour bar of the change colouring (ratio ticks), titled ``title``."""
    top = CHANGE_MAX_RATIO
    values = (1 / top, 0.5, 1.0, 2.0, top)
    ticks = [(0.5 + 0.5 * np.log(v) / np.log(top), _ratio_text(v)) for v in values]
    return _bar_image(_diverging, ticks, title, "×", width, height)


def _bar_image(ramp, ticks, title: str, unit: str, width: int, height: int) -> np.ndarray:
    """A colour bar: ``title`` on top, ``ramp`` (fractions -> float RGB) as the bar, ``ticks``
    (``(fraction, text)``) under it and ``unit`` after the last tick."""
    image = np.full((height, width, 3), 255, dtype=np.uint8)
    scale = height / 64
    font, thickness = 0.3 * scale, max(1, round(scale))
    face = cv2.FONT_HERSHEY_SIMPLEX
    (title_w, title_h), _ = cv2.getTextSize(title, face, font, thickness)
    title_font = min(font, font * (width - round(12 * scale)) / max(title_w, 1))  # fits
    _put(image, title, (round(6 * scale), round(3 * scale) + title_h), title_font, thickness)
    (unit_width, _), _ = cv2.getTextSize(unit, face, font, thickness)
    left, right = round(14 * scale), width - unit_width - round(24 * scale)
    top, bottom = round(8 * scale) + title_h, round(40 * scale)
    image[top:bottom, left:right] = _to_uint8(ramp(np.linspace(0.0, 1.0, right - left)))[None]
    cv2.rectangle(image, (left - 1, top - 1), (right, bottom), (90, 90, 90), 1)
    x = w = baseline = 0
    for fraction, text in ticks:
        x = left + round(float(fraction) * (right - left - 1))
        cv2.line(image, (x, bottom), (x, bottom + round(4 * scale)), (60, 60, 60), 1)
        (w, h), _ = cv2.getTextSize(text, face, font, thickness)
        baseline = bottom + round(6 * scale) + h
        _put(image, text, (x - w // 2, baseline), font, thickness)
    _put(image, unit, (x + w // 2 + round(5 * scale), baseline), font, thickness)
    return image


def _put(image: np.ndarray, text: str, origin: tuple[int, int], font: float, thick: int) -> None:
    # Hershey fonts have no "×" or "÷": draw ASCII stand-ins.
    ascii_text = text.replace("×", "x").replace("÷", "/")
    cv2.putText(image, ascii_text, origin, cv2.FONT_HERSHEY_SIMPLEX, font, (40, 40, 40), thick,
                cv2.LINE_AA)  # fmt: skip


def _ratio_text(value: float) -> str:
    return f"1/{1 / value:g}" if value < 1 else f"{value:g}"


def _log_fraction(values_cm: np.ndarray) -> np.ndarray:
    """Position in [0, 1] on the log scale of ``(...)`` centimetres (clipped)."""
    values = np.maximum(np.nan_to_num(np.asarray(values_cm, dtype=np.float64)), 1e-6)
    span = np.log(LOG_TOP_CM / LOG_BOTTOM_CM)
    return np.clip(np.log(values / LOG_BOTTOM_CM) / span, 0.0, 1.0)


def _diverging(fraction: np.ndarray) -> np.ndarray:
    """``(..., 3)`` float RGB of positions ``(...)`` in [0, 1] on the diverging map."""
    position = np.clip(np.asarray(fraction, dtype=np.float64), 0.0, 1.0)
    scaled = position * (len(DIVERGING_ANCHORS) - 1)
    lower = np.minimum(np.floor(scaled).astype(np.int64), len(DIVERGING_ANCHORS) - 2)
    weight = (scaled - lower)[..., None]
    return DIVERGING_ANCHORS[lower] * (1.0 - weight) + DIVERGING_ANCHORS[lower + 1] * weight


def _to_uint8(colours: np.ndarray) -> np.ndarray:
    return np.round(np.clip(colours, 0.0, 1.0) * 255.0).astype(np.uint8)


def _tick_values(max_cm: float) -> list[float]:
    """About five round tick values from 0 to ``max_cm``."""
    raw = max_cm / 5.0
    magnitude = 10.0 ** np.floor(np.log10(raw))
    step = min((m * magnitude for m in (1.0, 2.0, 2.5, 5.0, 10.0)), key=lambda s: abs(s - raw))
    return [float(v) for v in np.arange(0.0, max_cm + 1e-9, step)]
