"""BlazePose's hand and foot landmarks (knuckles, thumbs, heels, toes) drawn on the explorer's
photo: filled squares where the fit used them as evidence, hollow squares where it did not
(doubtful, outside the photo, or under a box: ``NetworkInput.extremity_evidence``), the same
marks as hkpd-predict's overview. The Photo tab's "Hand and foot landmarks" checkbox
(:mod:`hkpd.explorer.panels.landmarks`) hides them.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np
import viser

from hkpd.explorer.photo_geometry import PhotoPlacement
from hkpd.explorer.scene import OVERLAY_LIFT, ExplorerScene

MARK_COLOUR = (40, 170, 255)
"""Light blue: apart from the keypoints' green and red."""

MARK_SIZE_M = 0.016
"""A mark's side in scene metres (the keypoints' dots are 0.018)."""

FILLED_NODE = "/photo/landmarks/evidence"
HOLLOW_NODE = "/photo/landmarks/not_evidence"


@dataclass(frozen=True)
class LandmarkMarks:
    """One prediction's detected landmarks.

    Attributes:
        points: ``(L, 2)`` photo pixels (pixel-centre coordinates), finite.
        evidence: ``(L,)`` bool, which of them the fit used.
    """

    points: np.ndarray
    evidence: np.ndarray


def marks_of(posterior: object | None) -> LandmarkMarks | None:
    """The detected hand and foot landmarks of a posterior (None: none detected, e.g. a
    provider without BlazePose's extra landmarks, or no posterior)."""
    network_input = getattr(posterior, "network_input", None)
    points = getattr(getattr(network_input, "detection", None), "extremities", None)
    if points is None:
        return None
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    evidence = getattr(network_input, "extremity_evidence", None)
    evidence = (
        np.zeros(len(points), bool) if evidence is None else np.asarray(evidence, bool).ravel()
    )
    if evidence.shape != (len(points),):
        raise ValueError(f"{len(points)} landmarks but {evidence.shape} evidence flags")
    finite = np.isfinite(points).all(axis=1)
    return LandmarkMarks(points[finite], evidence[finite])


def photo_points(placement: PhotoPlacement, pixels: np.ndarray) -> np.ndarray:
    """``(..., 2)`` photo pixels (pixel-centre) -> ``(..., 3)`` points in the photo's frame,
    lifted off the photo as its other overlays are."""
    local = placement.pixels_to_local(np.asarray(pixels, dtype=np.float64) + 0.5)
    lift = np.full((*local.shape[:-1], 1), OVERLAY_LIFT)
    return np.concatenate([local, lift], axis=-1).astype(np.float32)


def hollow_squares(centres: np.ndarray, side: float) -> np.ndarray:
    """``(n, 3)`` centres -> ``(4 n, 2, 3)`` the four edges of a square of ``side`` about each,
    in the centres' x-y plane."""
    half = side / 2
    corners = np.array([[-half, -half], [half, -half], [half, half], [-half, half]])
    corners = np.concatenate([corners, np.zeros((4, 1))], axis=1)
    ring = centres[:, None] + corners[None]  # (n, 4, 3)
    edges = np.stack([ring, np.roll(ring, -1, axis=1)], axis=2)  # (n, 4, 2, 3)
    return edges.reshape(-1, 2, 3).astype(np.float32)


class ExtremityMarks:
    """Draws the current prediction's landmarks on the photo, and hides or shows them.

    Safe to call from the worker (:meth:`show`) and from GUI callbacks (:meth:`set_visible`)
    at once.
    """

    def __init__(self, scene: ExplorerScene, visible: bool = True) -> None:
        self.scene = scene
        self.visible = visible
        self.marks: LandmarkMarks | None = None
        self.filled: viser.PointCloudHandle | None = None
        self.hollow: viser.LineSegmentsHandle | None = None
        self._lock = threading.Lock()

    def show(self, posterior: object | None) -> None:
        """Draw ``posterior``'s detected landmarks (None: remove the marks)."""
        with self._lock:
            self.marks = marks_of(posterior)
            self._draw()

    def set_visible(self, visible: bool) -> None:
        """Show or hide the marks (the checkbox)."""
        with self._lock:
            self.visible = bool(visible)
            for node in (self.filled, self.hollow):
                if node is not None:
                    node.visible = self.visible

    def _draw(self) -> None:
        for node in (self.filled, self.hollow):
            if node is not None:
                node.remove()
        self.filled = self.hollow = None
        placement, marks = self.scene.placement, self.marks
        if placement is None or marks is None or not len(marks.points):
            return
        shown = placement.on_photo(marks.points)  # none drawn beside or below the photo
        marks = LandmarkMarks(marks.points[shown], marks.evidence[shown])
        centres = photo_points(placement, marks.points)
        api = self.scene.server.scene
        if marks.evidence.any():
            shown = centres[marks.evidence]
            self.filled = api.add_point_cloud(
                FILLED_NODE, shown, np.tile(np.array(MARK_COLOUR, np.uint8), (len(shown), 1)),
                point_size=MARK_SIZE_M, point_shape="square", point_shading="flat",
                visible=self.visible,
            )  # fmt: skip
        if not marks.evidence.all():
            edges = hollow_squares(centres[~marks.evidence], MARK_SIZE_M)
            self.hollow = api.add_line_segments(
                HOLLOW_NODE, edges, np.broadcast_to(np.array(MARK_COLOUR, np.uint8),
                                                   (*edges.shape[:2], 3)),
                thickness=1.5, thickness_units="screen", visible=self.visible,
            )  # fmt: skip
