"""The Photo tab's "Second keypoint reader" folder: a checkbox drawing MoveNet Thunder's
keypoints on the photo beside BlazePose's (:mod:`hkpd.explorer.second_reader_marks`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import viser

SECOND_READER_HINT = (
    "A second, independent keypoint reader (MoveNet) reads the same person: its keypoints in "
    "magenta beside BlazePose's. Where the two agree the fit uses both; where they disagree the "
    "body stays uncertain there and the quality line may warn."
)


class SecondReaderActions(Protocol):
    """What the second reader section asks of the app."""

    def show_second_reader(self, visible: bool) -> None:
        """Draw the second reader's keypoints on the photo, or hide them."""
        ...


@dataclass(frozen=True)
class SecondReaderSection:
    """Handles of the section.

    Attributes:
        show: "Show on the photo" (default off).
    """

    show: viser.GuiCheckboxHandle


def build_second_reader_section(
    gui: viser.GuiApi, actions: SecondReaderActions
) -> SecondReaderSection:
    """Lay out the folder and wire its checkbox to ``actions.show_second_reader``."""
    with gui.add_folder("Second keypoint reader", expand_by_default=False):
        show = gui.add_checkbox("Show on the photo", initial_value=False, hint=SECOND_READER_HINT)

    @show.on_update
    def _(_event: viser.GuiEvent) -> None:
        actions.show_second_reader(bool(show.value))

    return SecondReaderSection(show)
