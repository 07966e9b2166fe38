"""What every section's callbacks may reach: the shared state and the "samples are stale" call.

Each section module declares a small protocol of the app calls its callbacks make (its
*actions*), built on :class:`StateActions`; :class:`hkpd.explorer.panels.PanelActions` is their
union, and ``ExplorerApp`` implements it. A callback only changes the state and says what became
stale; nothing heavy runs in it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    from hkpd.explorer.state import ExplorerState


class StateActions(Protocol):
    """The state every tab shares, and the call that redraws the samples after a change."""

    state: ExplorerState

    def sampling_changed(self, changed: bool) -> None:
        """Draw new samples when ``changed`` (coalesced in the worker)."""
        ...
