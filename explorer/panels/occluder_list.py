"""The list of occluders in the photo tab: one folder per box with an on/off switch, exact
position sliders (photo pixels) and a delete button, rebuilt when boxes come or go."""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import viser

from hkpd.explorer.panels.actions import StateActions
from hkpd.explorer.state import Occluder

CORNER_LABELS = ("x0", "y0", "x1", "y1")


class OccluderActions(StateActions, Protocol):
    """What an occluder's controls ask of the app."""

    def occluders_changed(self, changed: bool) -> bool:
        """Redraw the boxes and predict again when ``changed``."""
        ...


@dataclass(frozen=True)
class OccluderControls:
    """Handles of one occluder's folder.

    Attributes:
        folder: "Occluder #ident".
        enabled: "On".
        corners: the ``x0, y0, x1, y1`` sliders (photo pixels).
        delete: "Delete".
    """

    folder: viser.GuiFolderHandle
    enabled: viser.GuiCheckboxHandle
    corners: tuple[viser.GuiSliderHandle, ...]
    delete: viser.GuiButtonHandle


class OccluderList:
    """The dynamic part of the photo tab (thread-safe: the list is rebuilt from the worker and
    from GUI callbacks).

    Args:
        gui: viser's global GUI.
        folder: the folder the list lives in.
        actions: where the controls' edits go.
    """

    def __init__(
        self, gui: viser.GuiApi, folder: viser.GuiFolderHandle, actions: OccluderActions
    ) -> None:
        self._gui = gui
        self._folder = folder
        self._actions = actions
        self._lock = threading.RLock()
        self._handles: list[viser.GuiFolderHandle] = []
        self._signature: tuple = ()
        self._controls: dict[int, OccluderControls] = {}

    def controls(self, ident: int) -> OccluderControls:
        """The controls of occluder ``ident``; KeyError when it is not listed."""
        with self._lock:
            return self._controls[ident]

    def show(self, occluders: tuple[Occluder, ...], image_size: tuple[int, int]) -> None:
        """Rebuild the list when occluders were added, deleted or toggled (by any tab); else
        move the sliders of boxes that moved."""
        with self._lock:
            signature = (*((o.ident, o.enabled) for o in occluders), image_size)
            if signature == self._signature:
                self._sync_sliders(occluders)
                return
            self._signature = signature
            for handle in self._handles:
                handle.remove()
            self._handles, self._controls = [], {}
            with self._folder:
                if not occluders:
                    self._handles.append(self._gui.add_folder("(none yet)"))
                for occluder in occluders:
                    controls = self._add_occluder(occluder, image_size)
                    self._handles.append(controls.folder)
                    self._controls[occluder.ident] = controls

    def _add_occluder(self, occluder: Occluder, image_size: tuple[int, int]) -> OccluderControls:
        gui, state, ident = self._gui, self._actions.state, occluder.ident
        with gui.add_folder(f"Occluder #{ident}") as folder:
            enabled = gui.add_checkbox("On", occluder.enabled)
            corners = tuple(
                gui.add_slider(label, 0.0, float(image_size[k % 2]), 1.0, float(occluder.box[k]))
                for k, label in enumerate(CORNER_LABELS)
            )
            delete = gui.add_button("Delete", color="red", icon=viser.Icon.TRASH)
        self._on_update(enabled, lambda: state.set_occluder_enabled(ident, enabled.value))
        for slider in corners:
            self._on_update(
                slider, lambda: state.move_occluder(ident, tuple(float(s.value) for s in corners))
            )
        delete.on_click(lambda _: self._actions.occluders_changed(state.delete_occluder(ident)))
        return OccluderControls(folder, enabled, corners, delete)

    def _on_update(
        self, handle: viser.GuiCheckboxHandle | viser.GuiSliderHandle, edit: Callable[[], bool]
    ) -> None:
        """Apply ``edit`` to the state when ``handle`` changes, and say whether it changed."""
        handle.on_update(lambda _: self._actions.occluders_changed(edit()))

    def _sync_sliders(self, occluders: tuple[Occluder, ...]) -> None:
        for occluder in occluders:
            listed = self._controls.get(occluder.ident)
            for slider, value in zip(listed.corners if listed else (), occluder.box, strict=False):
                if abs(slider.value - value) > 0.5:
                    slider.value = round(value)
