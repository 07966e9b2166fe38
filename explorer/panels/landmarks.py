"""The Photo tab's "Hand and foot landmarks" folder: a checkbox drawing BlazePose's knuckles,
thumbs, heels and toes on the photo (:mod:`hkpd.explorer.extremity_marks`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import viser

LANDMARKS_HINT = (
    "BlazePose's hand and foot landmarks (knuckles, thumbs, heels, toes) on the photo: filled "
    "squares were evidence for the fit (they turn the hands and feet), hollow ones were not "
    "(doubtful, or under a box)."
)


class LandmarkActions(Protocol):
    """What the landmarks section asks of the app."""

    def show_landmarks(self, visible: bool) -> None:
        """Draw the detected hand and foot landmarks on the photo, or hide them."""
        ...


@dataclass(frozen=True)
class LandmarkSection:
    """Handles of the section.

    Attributes:
        show: "Show on the photo" (default on).
    """

    show: viser.GuiCheckboxHandle


def build_landmark_section(gui: viser.GuiApi, actions: LandmarkActions) -> LandmarkSection:
    """Lay out the folder and wire its checkbox to ``actions.show_landmarks``."""
    with gui.add_folder("Hand and foot landmarks", expand_by_default=False):
        show = gui.add_checkbox("Show on the photo", initial_value=True, hint=LANDMARKS_HINT)

    @show.on_update
    def _(_event: viser.GuiEvent) -> None:
        actions.show_landmarks(bool(show.value))

    return LandmarkSection(show)
