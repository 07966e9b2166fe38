"""The photo tab's "Same person, more photos" folder: add photos of the current person to
sharpen their shape, and say what the combined shape is made of."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import viser

ONLY_CURRENT_PHOTO = "*Only the current photo so far.*"


class SamePersonActions(Protocol):
    """What the same-person section asks of the app."""

    def add_same_person_upload(
        self, name: str, content: bytes, client: viser.ClientHandle | None
    ) -> None:
        """Check an uploaded photo of the same person and add its shape."""
        ...

    def clear_same_person(self) -> None:
        """Forget the added photos."""
        ...


@dataclass(frozen=True)
class SamePersonSection:
    """Handles of the same-person folder.

    Attributes:
        upload: "Add a photo of the same person".
        text: the photos and the combined vs the current photo's std.
        clear: "Forget the added photos".
    """

    upload: viser.GuiUploadButtonHandle
    text: viser.GuiMarkdownHandle
    clear: viser.GuiButtonHandle

    def show(self, text: str) -> None:
        """What the combined shape is made of (photos, std), or that there is none."""
        self.text.content = text


def build_same_person_section(gui: viser.GuiApi, actions: SamePersonActions) -> SamePersonSection:
    """The "Same person, more photos" folder (collapsed), wired to ``actions``."""
    with gui.add_folder("Same person, more photos", expand_by_default=False):
        gui.add_markdown(
            "*More photos of the person in the current photo sharpen their shape: the "
            "shape distributions are multiplied (right-most body, T-pose, coloured by "
            "shape uncertainty).*"
        )
        upload = gui.add_upload_button(
            "Add a photo of the same person",
            icon=viser.Icon.USER_PLUS,
            mime_type="image/*",
            hint="Only its shape is used; the current photo stays on screen",
        )
        text = gui.add_markdown(ONLY_CURRENT_PHOTO)
        clear = gui.add_button("Forget the added photos", icon=viser.Icon.TRASH)
    upload.on_upload(
        lambda event: actions.add_same_person_upload(
            upload.value.name, upload.value.content, event.client
        )
    )
    clear.on_click(lambda _: actions.clear_same_person())
    return SamePersonSection(upload, text, clear)
