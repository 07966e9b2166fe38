"""The photo tab's "Scene" folder: save the scene to a file and load one, undo and redo the
last edits, reset everything, and a line listing what differs from the defaults."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import viser

NO_CHANGES = "*Everything at its defaults.*"


class KeepActions(Protocol):
    """What the scene section asks of the app."""

    def save_scene(self, client: viser.ClientHandle | None) -> None:
        """Send the current scene as a JSON file to ``client``."""
        ...

    def load_scene_upload(
        self, name: str, content: bytes, client: viser.ClientHandle | None
    ) -> None:
        """Open an uploaded scene file (or exported page); errors notify ``client``."""
        ...

    def undo(self) -> bool:
        """Back to the edit before."""
        ...

    def redo(self) -> bool:
        """Forward to the edit undone last."""
        ...

    def reset_everything(self) -> None:
        """Every setting back to its default; the photo stays."""
        ...


@dataclass(frozen=True)
class KeepSection:
    """Handles of the "Scene" folder.

    Attributes:
        save: "Save scene" (downloads ``hkpd_scene.json``).
        load: "Load scene" (a scene file, or a page exported by hkpd).
        undo, redo: the last edits (boxes, sliders, switches, person box).
        reset: "Reset everything".
        changes: what differs from the defaults.
    """

    save: viser.GuiButtonHandle
    load: viser.GuiUploadButtonHandle
    undo: viser.GuiButtonHandle
    redo: viser.GuiButtonHandle
    reset: viser.GuiButtonHandle
    changes: viser.GuiMarkdownHandle

    def show_changes(self, text: str) -> None:
        """``text``: the settings that differ from the defaults ("" when none)."""
        content = f"**Not default:** {text}" if text else NO_CHANGES
        if self.changes.content != content:
            self.changes.content = content


def build_keep_section(gui: viser.GuiApi, actions: KeepActions) -> KeepSection:
    """The "Scene" folder, wired to ``actions``."""
    with gui.add_folder("Scene"):
        changes = gui.add_markdown(NO_CHANGES)
        save = gui.add_button(
            "Save scene", icon=viser.Icon.DEVICE_FLOPPY,
            hint="Download the photo, boxes, sliders and settings as a scene file (JSON); "
            "reopen it with Load scene or hkpd-explore --scene FILE",
        )  # fmt: skip
        load = gui.add_upload_button(
            "Load scene", icon=viser.Icon.FOLDER_OPEN, mime_type=".json,.html",
            hint="A scene file saved here or by hkpd-explore --save-scene, or a page exported "
            "by hkpd",
        )  # fmt: skip
        undo = gui.add_button("Undo", icon=viser.Icon.ARROW_BACK_UP)
        redo = gui.add_button("Redo", icon=viser.Icon.ARROW_FORWARD_UP)
        reset = gui.add_button("Reset everything", icon=viser.Icon.RESTORE)
    save.on_click(lambda event: actions.save_scene(event.client))
    load.on_upload(
        lambda event: actions.load_scene_upload(load.value.name, load.value.content, event.client)
    )
    undo.on_click(lambda _: actions.undo())
    redo.on_click(lambda _: actions.redo())
    reset.on_click(lambda _: actions.reset_everything())
    return KeepSection(save, load, undo, redo, reset, changes)
