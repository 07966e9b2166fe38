"""The "Export" folder: the mode and the displayed samples as GLB or PLY, a PNG screenshot
rendered by the browser, and the scene as one self-contained HTML page (for slides and course
pages: it opens without a server)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import viser

MESH_FORMATS = ("glb", "ply")


class ExportActions(Protocol):
    """What the export section asks of the app (each answers the client that clicked)."""

    def request_export(self, file_format: str, client: viser.ClientHandle) -> None:
        """Send the meshes as ``file_format`` (one of :data:`MESH_FORMATS`)."""
        ...

    def request_screenshot(self, client: viser.ClientHandle) -> None:
        """Send a PNG of the client's view."""
        ...

    def request_page(self, client: viser.ClientHandle) -> None:
        """Send the current scene as one self-contained HTML page with its caption."""
        ...


@dataclass(frozen=True)
class ExportSection:
    """Handles of the export buttons.

    Attributes:
        meshes: one button per mesh format, by format.
        screenshot: "Screenshot (PNG)".
        page: "Export page (HTML)".
    """

    meshes: dict[str, viser.GuiButtonHandle]
    screenshot: viser.GuiButtonHandle
    page: viser.GuiButtonHandle


def build_export_section(gui: viser.GuiApi, actions: ExportActions) -> ExportSection:
    """The "Export" folder (collapsed), wired to ``actions``."""
    with gui.add_folder("Export", expand_by_default=False):
        meshes = {
            file_format: gui.add_button(f"Meshes ({file_format.upper()})", icon=viser.Icon.DOWNLOAD)
            for file_format in MESH_FORMATS
        }
        screenshot = gui.add_button("Screenshot (PNG)", icon=viser.Icon.CAMERA)
        page = gui.add_button(
            "Export page (HTML)",
            icon=viser.Icon.FILE_CODE,
            hint="The scene as one HTML file that opens without a server (slides, course pages)",
        )
    for file_format, button in meshes.items():
        button.on_click(_export_callback(actions, file_format))
    screenshot.on_click(lambda event: actions.request_screenshot(event.client))
    page.on_click(lambda event: actions.request_page(event.client))
    return ExportSection(meshes, screenshot, page)


def _export_callback(actions: ExportActions, file_format: str) -> Callable[[viser.GuiEvent], None]:
    def callback(event: viser.GuiEvent) -> None:
        actions.request_export(file_format, event.client)

    return callback
