"""Notifications that replace each other: one per browser tab and title, so that repeated
ones ("Weak keypoints" after every prediction, "No occluder drawn" after every short drag) do
not pile up over the scene; a newer notification with the same title takes the older's place.
"""

from __future__ import annotations

import contextlib
import threading
from typing import Any

ERROR_SECONDS, INFO_SECONDS = 8.0, 3.0
"""How long a notification stays: errors longer."""


class Notices:
    """Shows notifications in tabs (viser ``ClientHandle``s), replacing older ones of the same
    title in the same tab. Thread-safe."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._shown: dict[tuple[Any, str], Any] = {}

    def show(self, client: Any, title: str, body: str, error: bool = False) -> None:
        """Show ``title`` / ``body`` in ``client``'s tab (red and longer when ``error``), in
        place of the last notification with this title there."""
        handle = client.add_notification(
            title, body, auto_close_seconds=ERROR_SECONDS if error else INFO_SECONDS,
            color="red" if error else None,
        )  # fmt: skip
        key = (getattr(client, "client_id", id(client)), title)
        with self._lock:
            previous, self._shown[key] = self._shown.get(key), handle
        remove = getattr(previous, "remove", None)
        if remove is not None:
            # Closed already, or the tab is gone: nothing to replace.
            with contextlib.suppress(Exception):
                remove()


NOTICES = Notices()
"""The app's notifications (every tab of every app in this process)."""
