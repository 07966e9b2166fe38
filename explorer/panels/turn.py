"""The photo tab's "Facing" folder: the *Turn around* button, which shows the person's
turned-around reading (the same keypoints fitted by a body facing the other way, left and
right swapped: :meth:`hkpd.prediction.BodyPosterior.turned_around`) and turns it back.

Under the explorer's weak-perspective camera a body and its depth-mirrored twin project to the
same points, so one photo cannot tell which way a person faces when the face is hidden:
BlazePose labels most people seen from behind as facing the camera (``docs/evidence.md``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import viser

TURN, TURN_BACK = "Turn around", "Turn back"
"""The button's label while the reading is as predicted, and while it is turned around."""
AS_READ = "*Facing as read from the photo.* Seen from behind? Try **Turn around**."
TURNED = (
    "**Turned around:** the same keypoints fitted by a body facing the other way (left and "
    "right swapped)."
)


class TurnActions(Protocol):
    """What the facing section asks of the app."""

    def set_turned_around(self, enabled: bool) -> None:
        """Show the turned-around reading (True) or the reading as predicted."""
        ...


@dataclass(frozen=True)
class TurnSection:
    """Handles of the "Facing" folder.

    Attributes:
        button: *Turn around* / *Turn back*.
        note: which reading is shown, or why it could not be turned.
    """

    button: viser.GuiButtonHandle
    note: viser.GuiMarkdownHandle

    @property
    def turned(self) -> bool:
        """The button offers to turn back (the turned reading is asked for)."""
        return self.button.label == TURN_BACK

    def show(self, wanted: bool, shown: bool | None, reason: str = "") -> None:
        """The button for ``wanted`` (the state's setting) and the line for what is ``shown``:
        True, the turned reading; False, the reading as predicted; None, no person yet.
        ``reason``: why a wanted turn is not shown."""
        label = TURN_BACK if wanted else TURN
        if self.button.label != label:
            self.button.label = label
        if shown is None:
            text = ""
        elif wanted and not shown:
            text = f"**Not turned around:** {reason or 'this reading cannot be turned'}"
        else:
            text = TURNED if shown else AS_READ
        if self.note.content != text:
            self.note.content = text


def build_turn_section(gui: viser.GuiApi, actions: TurnActions) -> TurnSection:
    """The "Facing" folder, wired to ``actions``."""
    with gui.add_folder("Facing", expand_by_default=False):
        button = gui.add_button(
            TURN, icon=viser.Icon.ROTATE_360,
            hint="Fit the same keypoints with a body facing the other way (left and right "
            "swapped): for a person seen from behind whom the detector read as facing the "
            "camera. Click again to turn back.",
        )  # fmt: skip
        note = gui.add_markdown("")
    section = TurnSection(button, note)
    button.on_click(lambda _: actions.set_turned_around(not section.turned))
    return section
