"""The explorer when nobody is found (issues 42 and 44), without a browser: the photo is drawn
so that the person can be picked on it, the last person's body is cleared, the Person menu
follows a picked box, and a person box holding no person gets a warning. The test double of the
predictor (``test_explorer_double.py``) stands in for the model."""

from __future__ import annotations

import io
import threading
import time
from types import SimpleNamespace

import numpy as np
from PIL import Image
from test_explorer_app import RecordingClient, TwoPeopleProvider
from test_explorer_double import OcclusionAwareDouble

from hkpd.explorer.app import ExplorerApp, weak_keypoints_warning
from hkpd.explorer.colour_map import COLOURINGS
from hkpd.explorer.panels.photo import PICKED_CHOICE
from hkpd.prediction.detection.keypoint_detector import NoPersonFoundError


def nodes(explorer: ExplorerApp) -> set[str]:
    return set(explorer.server.scene._handle_from_node_name)


class NobodyOutsideBoxes:
    """The test double, except that nobody is found without a person box, nor in ``EMPTY``."""

    EMPTY = (300.0, 10.0, 380.0, 100.0)

    def __init__(self) -> None:
        self.double = OcclusionAwareDouble()

    def predict(self, image, occluders, evidence=True, bbox=None):
        if bbox is None or tuple(bbox) == self.EMPTY:
            raise NoPersonFoundError("photo: no person found")
        return self.double.predict(image, occluders, evidence, bbox)

    def find_people(self, image):
        return []


def test_a_photo_without_a_person_is_drawn_to_pick_the_person_on():
    provider = NobodyOutsideBoxes()
    explorer = ExplorerApp(provider, provider.double.scene.image, port=0)
    try:
        assert explorer.wait_idle(30)
        assert explorer.scene.placement is not None and "/photo" in nodes(explorer)
        assert explorer.view is None and "/body/mode" not in nodes(explorer)
        assert "Pick the person" in explorer.panels.status.line.content
        assert "--bbox" not in explorer.panels.status.line.content
        explorer.pick_person_next()
        assert explorer.set_person_box((20, 20, 300, 500))
        assert explorer.wait_idle(30) and explorer.view is not None
        assert "/body/mode" in nodes(explorer) and "/photo/person_box" in nodes(explorer)
        assert not explorer.errors
    finally:
        explorer.stop()


def test_nobody_in_a_new_box_clears_the_last_persons_body():
    provider = NobodyOutsideBoxes()
    explorer = ExplorerApp(provider, provider.double.scene.image, port=0)
    try:
        assert explorer.set_person_box((20, 20, 300, 500)) and explorer.wait_idle(30)
        drawn = {"/body/mode", "/heat/points", "/photo/keypoints", "/photo/reprojection",
                 "/joint_axes_label", "/legend"}  # fmt: skip
        assert drawn <= nodes(explorer) and explorer.view is not None
        assert explorer.set_person_box(NobodyOutsideBoxes.EMPTY) and explorer.wait_idle(30)
        assert not drawn & nodes(explorer)  # no arrows line, no colour bar of the old body
        assert explorer.panels.teaching.axes_text.content == ""  # nor its concentrations
        assert explorer.view is None and explorer.result is None
        assert "/photo" in nodes(explorer) and "No person was found" in (
            explorer.panels.status.line.content
        )
        # Nobody in a picked box (a tiny person, issue 58): say what to do instead, not "Pick
        # the person" again, which is what found nobody.
        assert "drag a tighter box" in explorer.panels.status.line.content
        assert "Click **Pick the person**" not in explorer.panels.status.line.content
        assert explorer.set_person_box((20, 20, 300, 500)) and explorer.wait_idle(30)
        assert {"/legend", "/joint_axes_label"} <= nodes(explorer)  # drawn again with a body
    finally:
        explorer.stop()


def test_an_upload_without_a_person_is_loaded_and_drawn():
    double = OcclusionAwareDouble()
    provider = NobodyOutsideBoxes()
    explorer = ExplorerApp(provider, double.scene.image, port=0, person_box=(20, 20, 300, 500))
    try:
        assert explorer.wait_idle(30) and explorer.view is not None
        gradient = np.repeat(np.linspace(0, 255, 320, dtype=np.uint8)[None, :, None], 200, 0)
        buffer = io.BytesIO()
        Image.fromarray(np.repeat(gradient, 3, axis=2)).save(buffer, format="PNG")
        client = RecordingClient()
        explorer.load_upload("gradient.png", buffer.getvalue(), client)
        assert explorer.wait_idle(30)
        placement = explorer.scene.placement
        assert (placement.width_px, placement.height_px) == (320, 200)
        assert explorer.view is None and "/body/mode" not in nodes(explorer)
        # No colour bar nor arrows line of the last photo's body (placing the new photo drew
        # the titles, which drew the colour bar again), nor after a new colouring.
        assert not {"/legend", "/joint_axes_label"} & nodes(explorer)
        explorer.panels.samples.colouring.value = COLOURINGS["linear"]
        assert explorer.wait_idle(30) and "/legend" not in nodes(explorer)
        titles = [title for title, _ in client.notifications]
        assert titles == ["Photo loaded", "No person found"]
        assert "drag a box" in client.notifications[1][1] and "--bbox" not in str(titles)
    finally:
        explorer.stop()


def test_the_person_menu_follows_a_picked_box():
    provider = TwoPeopleProvider()
    explorer = ExplorerApp(provider, provider.double.scene.image, port=0, num_displayed=2)
    try:
        assert explorer.wait_idle(60)
        menu = explorer.panels.photo.people
        assert explorer.select_person(1) and explorer.wait_idle(30)
        assert menu.value.startswith("Person 2 of 2")
        assert explorer.set_person_box((150.0, 40.0, 330.0, 460.0)) and explorer.wait_idle(30)
        assert menu.value == PICKED_CHOICE and menu.visible
        assert explorer.set_person_box(None) and explorer.wait_idle(30)
        assert menu.value.startswith("Person 1 of 2")
        assert not explorer.errors
    finally:
        explorer.stop()


def test_a_people_search_ending_during_a_pick_leaves_the_picked_box_in_the_menu(monkeypatch):
    """The people lane sets the menu from the state as it read it; a pick in between must not
    be overwritten by that older menu (seen in CI: "(one person)" after a pick on a person-less
    upload). The menu is slowed down here so that the pick lands inside that window."""
    provider = NobodyOutsideBoxes()
    explorer = ExplorerApp(provider, provider.double.scene.image, port=0)
    try:
        assert explorer.wait_idle(30)
        section = explorer.panels.photo
        shown = type(section).show_people
        reading = threading.Event()

        def slow_show_people(self, count, choice=0, places=()):
            if threading.current_thread() is not threading.main_thread():
                reading.set()
                time.sleep(0.3)  # the search's menu, worked out before the pick
            shown(self, count, choice, places)

        monkeypatch.setattr(type(section), "show_people", slow_show_people)
        search = threading.Thread(target=explorer._show_person_menu)
        search.start()
        assert reading.wait(5)
        explorer.pick_person_next()
        assert explorer.set_person_box((20.0, 20.0, 300.0, 500.0))
        search.join(5)
        assert section.people.value == PICKED_CHOICE
        assert explorer.wait_idle(30) and not explorer.errors
    finally:
        explorer.stop()


def posterior_with(detector_score: float | None, evidence: int, search_box=(0, 0, 10, 10)):
    """Just what :func:`weak_keypoints_warning` reads of a posterior."""
    detection = SimpleNamespace(
        detector_score=detector_score,
        search_box=None if search_box is None else np.array(search_box, float),
        confidences=np.full(17, 0.4),
    )
    shown = np.arange(17) < evidence
    return SimpleNamespace(network_input=SimpleNamespace(detection=detection, evidence=shown))


def test_a_person_box_without_a_person_gets_a_weak_keypoints_warning():
    warning = weak_keypoints_warning(posterior_with(None, 7))
    assert "found nobody in the box" in warning and "7 of 17" in warning
    assert "only 3 keypoints" in weak_keypoints_warning(posterior_with(0.9, 3))
    assert weak_keypoints_warning(posterior_with(0.9, 12)) is None
    assert weak_keypoints_warning(posterior_with(None, 7, search_box=None)) is None
    assert weak_keypoints_warning(SimpleNamespace()) is None  # a custom provider's posterior


class CutOffFirstProvider(TwoPeopleProvider):
    """Two people: the larger one, whom the detector picks, cut off at the photo's right and
    bottom edges (the photo is 384 x 512), the other whole."""

    BOXES = ((200.0, 60.0, 384.0, 512.0), (20.0, 40.0, 190.0, 480.0))
    READ = (205.0, 66.0, 384.0, 512.0)
    """The person box of the first reading (made without a box): the cut-off person."""


def test_the_person_menu_says_where_each_is_and_shows_a_whole_person_first(monkeypatch):
    """Issue 58: "Person 2 of 4" said nothing of where that person is, and the detector's pick,
    cut off at the photo's edge, was shown though a whole person was found. Now each entry says
    where, and the whole person is shown, predicted in their listed box (as --all-people)."""
    from hkpd.prediction.posterior import BodyPosterior

    monkeypatch.setattr(BodyPosterior, "person_box", property(lambda _: CutOffFirstProvider.READ))
    provider = CutOffFirstProvider()
    explorer = ExplorerApp(provider, provider.double.scene.image, port=0, num_displayed=2)
    try:
        deadline = time.monotonic() + 60
        while len(provider.calls) < 2 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert explorer.wait_idle(60)
        assert provider.calls == [None, CutOffFirstProvider.BOXES[1]]
        menu = explorer.panels.photo.people
        assert tuple(menu.options) == (
            "Person 1 of 2 — right, large, cut off by the edge",
            "Person 2 of 2 — left, large",
        )
        assert menu.value == menu.options[1]
        assert explorer.state.snapshot().person_box == CutOffFirstProvider.BOXES[1]
        # ... and each listed person is outlined and numbered on the photo.
        drawn = nodes(explorer)
        assert {"/photo/people/number_1", "/photo/people/number_2"} <= drawn
        outlines = explorer.server.scene._handle_from_node_name["/photo/people/outlines"]
        assert len(outlines.points) == 8  # two boxes of four edges
        assert explorer.server.scene._handle_from_node_name["/photo/people/number_2"].text == "2"
        assert not explorer.errors
    finally:
        explorer.stop()


def test_person_places_and_whom_to_show() -> None:
    from hkpd.explorer.people_menu import person_places, person_to_show

    size = (1000, 600)
    people = ((600.0, 100.0, 1000.0, 600.0), (50.0, 100.0, 250.0, 500.0), (450, 300, 500, 400))
    assert person_places(people, size) == (
        "right, large, cut off by the edge", "left, medium", "centre, small",
    )  # fmt: skip
    assert person_to_show(people, (610.0, 90.0, 1000.0, 600.0), size) == 1  # whole one first
    assert person_to_show(people, (60.0, 100.0, 240.0, 490.0), size) == 1  # in its listed box
    assert person_to_show(people, None, size) is None  # unknown reading: kept
    assert person_to_show(people[:1], people[0], size) is None  # one person: kept
    assert person_to_show(people[::2], people[0], size) == 1
