"""The list of occluders in the photo tab: one folder per box with an on/off switch, exact
position sliders (photo pixels) and a delete button, rebuilt when boxes come or go.

The fields always show the box in use. An edit (one field typed, or dragged) is applied under
the list's lock: the four fields are read, the state takes the box (ordered, clipped, or
refused when too small), and any field that differs from the box the state now holds is set
to it. Fields are only ever set from the state's *current* box, never from an older snapshot,
so quick edits in a row cannot be undone by a redraw that was already under way. viser does not
echo a browser's own edit back to it, so a value the server sent just before the browser's
next edit arrived could stay on screen; a field edited within :data:`RESEND_WINDOW_S` of the
server setting it is therefore sent again.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import viser

from hkpd.explorer.panels.actions import StateActions
from hkpd.explorer.state import Occluder

CORNER_LABELS = ("x0", "y0", "x1", "y1")

RESEND_WINDOW_S = 2.0
"""A field edited this soon after the server set it is sent to the browsers again."""


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
        self._setting = threading.local()  # set while this thread assigns fields itself
        self._set_at: dict[int, float] = {}  # id(slider) -> when the server last set it

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
                for occluder in occluders:
                    self._show_box_in_use(occluder.ident)
                return
            self._signature = signature
            for handle in self._handles:
                handle.remove()
            self._handles, self._controls, self._set_at = [], {}, {}
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
            slider.on_update(lambda event: self._corner_edited(ident, event.target))
        delete.on_click(lambda _: self._actions.occluders_changed(state.delete_occluder(ident)))
        return OccluderControls(folder, enabled, corners, delete)

    def _on_update(
        self, handle: viser.GuiCheckboxHandle | viser.GuiSliderHandle, edit: Callable[[], bool]
    ) -> None:
        """Apply ``edit`` to the state when ``handle`` changes, and say whether it changed."""
        handle.on_update(lambda _: self._actions.occluders_changed(edit()))

    def _corner_edited(self, ident: int, edited: viser.GuiSliderHandle) -> None:
        """One field of occluder ``ident`` changed: move the box, then show the box in use."""
        if getattr(self._setting, "active", False):
            return  # this thread is setting the fields to the box already in use
        with self._lock:
            listed = self._controls.get(ident)
            if listed is None or edited not in listed.corners:
                return  # the list was rebuilt meanwhile (deleted, or a new photo)
            typed = tuple(float(slider.value) for slider in listed.corners)
            changed = self._actions.state.move_occluder(ident, typed)
            self._actions.occluders_changed(changed)
            self._show_box_in_use(ident, typed)
            recently_set = time.monotonic() - self._set_at.get(id(edited), -RESEND_WINDOW_S)
            if recently_set < RESEND_WINDOW_S:
                self._resend(edited)

    def _show_box_in_use(self, ident: int, read: tuple[float, ...] | None = None) -> None:
        """Set the fields of occluder ``ident`` that differ from the state's current box.

        With ``read`` (the values an edit read), a field that changed since is left alone: an
        edit of it is in flight and will be applied by its own callback.
        """
        listed = self._controls.get(ident)
        try:
            box = self._actions.state.occluder(ident).box
        except KeyError:
            return  # deleted meanwhile; the list is rebuilt by the deletion's redraw
        for k, slider in enumerate(listed.corners if listed else ()):
            if float(slider.value) == box[k] or (read is not None and slider.value != read[k]):
                continue
            self._set(slider, box[k])

    def _set(self, slider: viser.GuiSliderHandle, value: float) -> None:
        """Assign ``value`` to ``slider`` without running this list's edit callback."""
        self._setting.active = True
        try:
            slider.value = value
        finally:
            self._setting.active = False
        self._set_at[id(slider)] = time.monotonic()

    def _resend(self, slider: viser.GuiSliderHandle) -> None:
        """Send ``slider``'s value to the browsers again (viser sends only changed values, so
        step away and back; the callback does not run)."""
        value = float(slider.value)
        away = value - slider.step if value - slider.step >= slider.min else value + slider.step
        self._set(slider, away)
        self._set(slider, value)
