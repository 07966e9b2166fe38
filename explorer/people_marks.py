"""The people the detector found, outlined and numbered on the photo while the Person menu
offers a choice (two or more people): "Person 2 of 4" then points at a box on the photo.

Each listed person's box is a thin grey outline with its number at the top-left corner (the
chosen person's box is also drawn in light blue, :meth:`ExplorerScene.show_person_box`).
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import viser

if TYPE_CHECKING:
    from hkpd.explorer.scene import ExplorerScene

Box = tuple[float, float, float, float]

OUTLINE_COLOUR = (150, 150, 150)
"""Grey: apart from the chosen person box's light blue and the occluders' dark boxes."""


class PeopleMarks:
    """Numbered outlines of the listed people on the photo (thread-safe)."""

    def __init__(self, scene: ExplorerScene) -> None:
        self.scene = scene
        self._nodes: list[viser.SceneNodeHandle] = []
        self._lock = threading.Lock()

    def show(self, people: Sequence[Box]) -> None:
        """Outline and number ``people`` (photo pixels, the Person menu's order) on the photo;
        fewer than two (no choice to make) removes the marks."""
        with self._lock:
            for node in self._nodes:
                node.remove()
            self._nodes = []
            placement = self.scene.placement
            if placement is None or len(people) < 2:
                return
            api = self.scene.server.scene
            edges = []
            for index, (x0, y0, x1, y1) in enumerate(people):
                pixels = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
                corners = self.scene.photo_points(pixels - 0.5)
                edges.append(np.stack([corners, np.roll(corners, -1, axis=0)], axis=1))
                self._nodes.append(api.add_label(
                    f"/photo/people/number_{index + 1}", str(index + 1),
                    position=tuple(corners[0]), anchor="bottom-left", font_screen_scale=1.0,
                ))  # fmt: skip
            segments = np.concatenate(edges).astype(np.float32)
            self._nodes.append(api.add_line_segments(
                "/photo/people/outlines", segments, OUTLINE_COLOUR, thickness=1.5,
                thickness_units="screen",
            ))  # fmt: skip
