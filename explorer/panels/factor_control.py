"""One multiplicative factor in the panel: a number box that holds the factor itself (typing 2
means 2×) and, under it, a track without a box that moves the same factor on a log10 scale
(0.1× .. 10×, 1× in the middle).

viser's slider always shows a number box bound to its own value, which for a log-scale slider
is log10 of the factor; a box-less track (viser's multi-slider with one handle) next to a
number box in factor units keeps every number a user sees or types in the unit its label
states. The two stay in step: each control's callback sets the other one only when they
disagree, so a change runs the owner's callback once per distinct value.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import viser

TRACK_MARKS = ((-1.0, "0.1×"), (0.0, "1×"), (1.0, "10×"))
TRACK_STEP = 0.05
"""Track step on log10 of the factor."""
BOX_STEP = 0.05
"""Step of the factor box's arrow keys."""
SAME = 1e-9
"""Exponents closer than this are the same value (a factor's log10 round trip)."""


class FactorControl:
    """A factor box ("left elbow ×", the factor) over a log10 track, kept in step.

    Args:
        gui: where to add the two controls.
        name: what the factor acts on ("left elbow").
        exponent_range: ``(low, high)`` log10 bounds of the factor (-1, 1: 0.1× .. 10×).
        hint: the hover text of both controls.

    Attributes:
        box: the number box; its value is the factor.
        track: the box-less track; its value is ``(log10 factor,)``.
    """

    def __init__(
        self, gui: viser.GuiApi, name: str, exponent_range: tuple[float, float], hint: str
    ) -> None:
        low, high = exponent_range
        self.name = name
        self._range = (float(low), float(high))
        self.box = gui.add_number(
            f"{name} ×", 1.0, min=10.0**low, max=10.0**high, step=BOX_STEP, hint=hint
        )
        self.track = gui.add_multi_slider(
            "", low, high, TRACK_STEP, (0.0,), marks=TRACK_MARKS, hint=hint
        )
        self._listeners: list[Callable[[float], None]] = []
        self.box.on_update(lambda _: self._box_changed())
        self.track.on_update(lambda _: self._track_changed())

    @property
    def exponent(self) -> float:
        """log10 of the factor the track shows (within the range)."""
        return float(self.track.value[0])

    @property
    def factor(self) -> float:
        """The factor, ``10 ** exponent``."""
        return 10.0**self.exponent

    def set_factor(self, factor: float) -> None:
        """Show ``factor`` (clipped to the range) in both controls; the listeners hear it."""
        self.set_exponent(math.log10(factor) if factor > 0 else -math.inf)

    def set_exponent(self, exponent: float) -> None:
        """Show the factor ``10 ** exponent`` (clipped to the range) in both controls."""
        self.track.value = (self._clip(exponent),)

    def on_change(self, listener: Callable[[float], None]) -> None:
        """Call ``listener(exponent)`` whenever the factor changes (from either control)."""
        self._listeners.append(listener)

    def _clip(self, exponent: float) -> float:
        low, high = self._range
        return round(min(max(float(exponent), low), high), 6)

    def _box_changed(self) -> None:
        """The box was typed in: move the track. An out-of-range number (a partly typed one,
        "0" on the way to "0.5") moves the track to the end but stays in the box: the browser
        clamps the box itself when the user leaves it."""
        value = float(self.box.value)
        exponent = self._clip(math.log10(value) if value > 0 else -math.inf)
        if abs(exponent - self.exponent) > SAME:
            self.track.value = (exponent,)

    def _track_changed(self) -> None:
        exponent = self._clip(self.exponent)
        box = float(self.box.value)
        shown = self._clip(math.log10(box) if box > 0 else -math.inf)
        if abs(shown - exponent) > SAME:
            self.box.value = 10.0**exponent
        for listener in self._listeners:
            listener(exponent)
