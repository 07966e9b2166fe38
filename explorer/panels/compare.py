"""The distribution tab's "Compare" folder: a second set of columns (B) for one alternative
setting of the same photo and person (:mod:`hkpd.explorer.compare`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import viser

from hkpd.explorer.compare import NAMED_SETTINGS, CompareSetting, parse_compare

OFF = "Off"
MODEL = "Another model (checkpoint path below)"
CHOICES = (OFF, *(f"B: {label}" for label in NAMED_SETTINGS.values()), MODEL)
"""The menu's entries: off, each named setting, another model."""


class CompareActions(Protocol):
    """What the compare section asks of the app."""

    def set_compare(self, setting: CompareSetting | None) -> None:
        """Compare against ``setting`` (None: no comparison); predicts B."""
        ...

    def compare_failed(self, message: str, client: viser.ClientHandle | None) -> None:
        """Say that a compare setting was refused."""
        ...


def choice_of(setting: CompareSetting | None) -> str:
    """The menu entry that stands for ``setting``."""
    if setting is None:
        return OFF
    return MODEL if setting.kind == "model" else f"B: {NAMED_SETTINGS[setting.kind]}"


@dataclass(frozen=True)
class CompareSection:
    """Handles of the "Compare" folder.

    Attributes:
        menu: what B is (:data:`CHOICES`).
        checkpoint: another model's checkpoint path (for :data:`MODEL`).
        numbers: B's numbers beside A's.
    """

    menu: viser.GuiDropdownHandle[str]
    checkpoint: viser.GuiTextHandle
    numbers: viser.GuiMarkdownHandle

    def show(self, setting: CompareSetting | None) -> None:
        """Show ``setting`` in the controls (a scene file or the command line set it)."""
        if setting is not None and setting.kind == "model":
            self.checkpoint.value = str(setting.checkpoint)
        self.checkpoint.visible = self.menu.value == MODEL or (
            setting is not None and setting.kind == "model"
        )
        if self.menu.value != choice_of(setting):
            self.menu.value = choice_of(setting)


def build_compare_section(gui: viser.GuiApi, actions: CompareActions) -> CompareSection:
    """The "Compare" folder, wired to ``actions``."""
    with gui.add_folder("Compare", expand_by_default=False):
        menu = gui.add_dropdown(
            "Compare with", CHOICES, initial_value=OFF,
            hint="B: the same photo and person with one setting changed, in a second set of "
            "columns; the change colouring then shows B's uncertainty ÷ A's",
        )  # fmt: skip
        checkpoint = gui.add_text("Checkpoint", "", visible=False)
        numbers = gui.add_markdown("")
    section = CompareSection(menu, checkpoint, numbers)
    menu.on_update(lambda event: _chosen(section, actions, event.client))
    checkpoint.on_update(lambda event: _chosen(section, actions, event.client))
    return section


def _chosen(
    section: CompareSection, actions: CompareActions, client: viser.ClientHandle | None
) -> None:
    choice = section.menu.value
    section.checkpoint.visible = choice == MODEL
    if choice == OFF:
        actions.set_compare(None)
    elif choice != MODEL:
        word = next(k for k, label in NAMED_SETTINGS.items() if choice == f"B: {label}")
        actions.set_compare(CompareSetting(word))
    elif section.checkpoint.value.strip():
        try:
            setting = parse_compare(section.checkpoint.value)
        except ValueError as error:
            actions.compare_failed(str(error).replace("--compare ", ""), client)
            return
        actions.set_compare(setting)
