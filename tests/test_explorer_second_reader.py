"""The explorer draws the second keypoint reader's keypoints on the photo (issue 59), hidden
until its checkbox asks (no browser)."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
import viser
from test_explorer_double import OcclusionAwareDouble

from hkpd.explorer.app import ExplorerApp
from hkpd.explorer.panels.second_reader import build_second_reader_section
from hkpd.explorer.photo_geometry import PhotoPlacement
from hkpd.explorer.scene import ExplorerScene
from hkpd.explorer.second_reader_marks import (
    LINE_NODE,
    POINT_NODE,
    SecondReaderMarks,
    second_marks_of,
)

POINTS = np.array([[200.0 + 8 * k, 100.0 + 15 * k] for k in range(17)])


def posterior_with(points: np.ndarray, scores: np.ndarray) -> SimpleNamespace:
    second = SimpleNamespace(keypoints=points, scores=scores)
    detection = SimpleNamespace(second_reading=second, search_box=None)
    return SimpleNamespace(network_input=SimpleNamespace(detection=detection))


@pytest.fixture(scope="module")
def server():
    server = viser.ViserServer(port=0, verbose=False)
    yield server
    server.stop()


def test_unsure_keypoints_are_not_drawn_nor_their_bones() -> None:
    scores = np.full(17, 0.8)
    scores[9] = 0.1  # the left wrist
    marks = second_marks_of(posterior_with(POINTS, scores))
    assert marks is not None and marks.shown.sum() == 16 and not marks.shown[9]
    assert second_marks_of(SimpleNamespace(network_input=None)) is None
    no_second = SimpleNamespace(network_input=SimpleNamespace(detection=SimpleNamespace()))
    assert second_marks_of(no_second) is None  # second_reader=False


def test_hidden_by_default_shown_on_request_and_gone_without_a_person(server) -> None:
    scene = ExplorerScene(server)
    scene.place_photo(np.zeros((480, 640, 3), np.uint8), PhotoPlacement(640, 480, (0, 1, 0), 1.8))
    marks = SecondReaderMarks(scene)
    scores = np.full(17, 0.8)
    scores[9] = 0.1
    marks.show(posterior_with(POINTS, scores))
    points, lines = marks.nodes
    assert len(points.points) == 16 and not points.visible and not lines.visible
    assert len(lines.points) == 16 - 1  # 16 bones, less the left forearm (wrist unsure)
    marks.set_visible(True)
    assert points.visible and lines.visible
    marks.show(None)
    names = server.scene._handle_from_node_name
    assert marks.nodes == [] and POINT_NODE not in names and LINE_NODE not in names


def test_the_checkbox_is_off_by_default_and_asks_the_app(server) -> None:
    server.gui.reset()
    calls: list[bool] = []
    section = build_second_reader_section(
        server.gui, SimpleNamespace(show_second_reader=lambda visible: calls.append(visible))
    )
    assert section.show.value is False
    section.show.value = True
    section.show.value = False
    assert calls == [True, False]


class SecondReaderDouble(OcclusionAwareDouble):
    """The explorer's test double, its posterior carrying a second reading near its keypoints."""

    def predict(self, image, occluders, evidence=True, bbox=None):
        result = super().predict(image, occluders, evidence, bbox)
        nearby = self.scene.keypoints2d[:17] + 3.0
        posterior = replace(result.posterior, network_input=posterior_with(
            nearby, np.full(17, 0.9)).network_input)  # fmt: skip
        return replace(result, posterior=posterior)


def test_the_app_draws_the_second_reading_when_asked() -> None:
    double = SecondReaderDouble()
    app = ExplorerApp(double, double.scene.image, port=0, num_displayed=2)
    try:
        assert app.wait_idle(60)
        points = app.second_reader_marks.nodes[0]
        assert not points.visible and len(points.points) >= 10
        app.show_second_reader(True)
        assert points.visible
    finally:
        app.stop()
