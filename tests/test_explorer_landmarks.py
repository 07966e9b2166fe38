"""The explorer draws BlazePose's hand and foot landmarks on the photo (filled where they were
evidence, hollow where not), and its checkbox hides them (no browser)."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
import viser
from test_explorer_double import OcclusionAwareDouble

from hkpd.explorer.app import ExplorerApp
from hkpd.explorer.extremity_marks import (
    FILLED_NODE,
    HOLLOW_NODE,
    ExtremityMarks,
    hollow_squares,
    marks_of,
)
from hkpd.explorer.panels.landmarks import build_landmark_section
from hkpd.explorer.photo_geometry import PhotoPlacement
from hkpd.explorer.scene import ExplorerScene

POINTS = np.array([[100.0 + 10 * i, 200.0 + 5 * i] for i in range(10)])
EVIDENCE = np.array([True] * 6 + [False, False, True, False])  # 7 of 10 shown


def posterior_with(points: np.ndarray, evidence: np.ndarray) -> SimpleNamespace:
    detection = SimpleNamespace(extremities=points, search_box=None)  # no weak-keypoint check
    return SimpleNamespace(
        network_input=SimpleNamespace(detection=detection, extremity_evidence=evidence)
    )


@pytest.fixture(scope="module")
def server():
    server = viser.ViserServer(port=0, verbose=False)
    yield server
    server.stop()


def test_marks_drop_missing_points_and_keep_their_evidence_flags() -> None:
    points = POINTS.copy()
    points[3] = np.nan  # a landmark BlazePose did not place
    marks = marks_of(posterior_with(points, EVIDENCE))
    assert marks is not None and len(marks.points) == 9
    assert marks.evidence.sum() == 6 and not marks.evidence[5]  # row 3 gone, rows after shift
    assert marks_of(SimpleNamespace(network_input=None)) is None  # a provider without them
    assert marks_of(None) is None
    with pytest.raises(ValueError, match="evidence flags"):
        marks_of(posterior_with(POINTS, EVIDENCE[:4]))
    edges = hollow_squares(np.zeros((2, 3)), 2.0)
    assert edges.shape == (8, 2, 3)
    assert np.allclose(np.abs(edges[..., :2]), 1.0) and np.allclose(edges[..., 2], 0.0)


def test_filled_where_evidence_hollow_where_not_and_the_switch_hides_both(server) -> None:
    scene = ExplorerScene(server)
    scene.place_photo(np.zeros((480, 640, 3), np.uint8), PhotoPlacement(640, 480, (0, 1, 0), 1.8))
    marks = ExtremityMarks(scene)
    marks.show(posterior_with(POINTS, EVIDENCE))
    assert marks.filled is not None and marks.hollow is not None
    assert len(marks.filled.points) == 7  # the shown ones, as squares
    assert len(marks.hollow.points) == 4 * 3  # four edges around each of the other three
    assert np.allclose(marks.filled.points[:, 2], marks.hollow.points[0, 0, 2], atol=1e-4)
    marks.set_visible(False)
    assert not marks.filled.visible and not marks.hollow.visible
    marks.show(posterior_with(POINTS, np.ones(10, bool)))  # a new prediction, still hidden
    assert marks.hollow is None and marks.filled is not None and not marks.filled.visible
    marks.set_visible(True)
    assert marks.filled.visible
    marks.show(None)  # no person: nothing stays behind
    names = server.scene._handle_from_node_name
    assert marks.filled is None and FILLED_NODE not in names and HOLLOW_NODE not in names


def test_the_checkbox_is_on_by_default_and_asks_the_app(server) -> None:
    server.gui.reset()
    calls: list[bool] = []
    section = build_landmark_section(
        server.gui, SimpleNamespace(show_landmarks=lambda visible: calls.append(visible))
    )
    assert section.show.value is True
    section.show.value = False
    section.show.value = True
    assert calls == [False, True]


class LandmarkDouble(OcclusionAwareDouble):
    """The explorer's test double, its posterior carrying detected landmarks (a box over the
    right foot makes them not evidence, as the predictor does)."""

    def predict(self, image, occluders, evidence=True, bbox=None):
        result = super().predict(image, occluders, evidence, bbox)
        shown = np.ones(10, bool)
        shown[[7, 9]] = not occluders
        ankles = self.scene.keypoints2d[[9, 10, 9, 10, 9, 10, 15, 16, 15, 16]] + 4.0
        posterior = replace(result.posterior, network_input=posterior_with(ankles, shown)
                            .network_input)  # fmt: skip
        return replace(result, posterior=posterior)


def test_the_app_draws_the_landmarks_and_hides_them_on_request() -> None:
    double = LandmarkDouble()
    app = ExplorerApp(double, double.scene.image, port=0, num_displayed=2)
    try:
        assert app.wait_idle(60)
        assert app.landmark_marks.filled is not None
        assert len(app.landmark_marks.filled.points) == 10 and app.landmark_marks.hollow is None
        app.show_landmarks(False)
        assert not app.landmark_marks.filled.visible
        app.show_landmarks(True)
        assert app.landmark_marks.filled.visible
    finally:
        app.stop()
