"""The second keypoint reader's reading (MoveNet Thunder, issue 59) drawn on the explorer's
photo: its keypoints as magenta dots joined by the skeleton's lines, beside BlazePose's green and
red dots, so a class sees where the two readers agree and where they do not. The Photo tab's
"Second keypoint reader" checkbox (:mod:`hkpd.explorer.panels.second_reader`) shows them (off by
default)."""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np
import viser

from hkpd.coco_keypoints import COCO17_LIMBS
from hkpd.explorer.extremity_marks import photo_points
from hkpd.explorer.scene import ExplorerScene

SECOND_COLOUR = (220, 60, 220)
"""Magenta: apart from BlazePose's green and red and the landmarks' blue."""

MIN_SCORE = 0.3
"""Keypoints Thunder scores below this are not drawn (as the second reader's evidence rule)."""

POINT_NODE = "/photo/second_reader/points"
LINE_NODE = "/photo/second_reader/lines"


@dataclass(frozen=True)
class SecondMarks:
    """One prediction's second reading.

    Attributes:
        points: ``(17, 2)`` photo pixels (pixel-centre coordinates).
        shown: ``(17,)`` bool: scored >= :data:`MIN_SCORE` and finite.
    """

    points: np.ndarray
    shown: np.ndarray


def second_marks_of(posterior: object | None) -> SecondMarks | None:
    """The second reader's keypoints of a posterior; None when it did not read the person
    (``second_reader=False``, a provider without it, no posterior)."""
    network_input = getattr(posterior, "network_input", None)
    second = getattr(getattr(network_input, "detection", None), "second_reading", None)
    if second is None:
        return None
    points = np.asarray(second.keypoints, dtype=np.float64).reshape(17, 2)
    shown = (np.asarray(second.scores, dtype=np.float64) >= MIN_SCORE) & np.isfinite(points).all(1)
    return SecondMarks(points, shown)


class SecondReaderMarks:
    """Draws the current prediction's second reading on the photo, and hides or shows it. Safe
    to call from the worker (:meth:`show`) and from GUI callbacks (:meth:`set_visible`)."""

    def __init__(self, scene: ExplorerScene, visible: bool = False) -> None:
        self.scene = scene
        self.visible = visible
        self.marks: SecondMarks | None = None
        self.nodes: list[viser.SceneNodeHandle] = []
        self._lock = threading.Lock()

    def show(self, posterior: object | None) -> None:
        """Draw ``posterior``'s second reading (None: remove it)."""
        with self._lock:
            self.marks = second_marks_of(posterior)
            self._draw()

    def set_visible(self, visible: bool) -> None:
        """Show or hide the marks (the checkbox)."""
        with self._lock:
            self.visible = bool(visible)
            for node in self.nodes:
                node.visible = self.visible

    def _draw(self) -> None:
        for node in self.nodes:
            node.remove()
        self.nodes = []
        placement, marks = self.scene.placement, self.marks
        if placement is None or marks is None:
            return
        shown = marks.shown & placement.on_photo(marks.points)
        if not shown.any():
            return
        api = self.scene.server.scene
        centres = photo_points(placement, marks.points)  # (17, 3)
        colour = np.array(SECOND_COLOUR, np.uint8)
        self.nodes.append(api.add_point_cloud(
            POINT_NODE, centres[shown], np.tile(colour, (int(shown.sum()), 1)),
            point_size=0.014, point_shape="circle", point_shading="flat", visible=self.visible,
        ))  # fmt: skip
        bones = [(a, b) for a, b in COCO17_LIMBS if shown[a] and shown[b]]
        if bones:
            segments = centres[np.array(bones)]  # (B, 2, 3)
            self.nodes.append(api.add_line_segments(
                LINE_NODE, segments, np.broadcast_to(colour, (*segments.shape[:2], 3)),
                thickness=1.5, thickness_units="screen", visible=self.visible,
            ))  # fmt: skip
