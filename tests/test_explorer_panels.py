"""The panel's sections without a browser: each builder wired to a recording stand-in for the
app, each control driven server-side (viser runs a handle's callbacks when the server assigns
its value, as when a browser does)."""

from __future__ import annotations

import math
import time
from concurrent.futures import ThreadPoolExecutor
from types import SimpleNamespace

import numpy as np
import pytest
import torch
import viser
from viser._messages import GuiUpdateMessage

from hkpd.explorer.colour_map import COLOURINGS
from hkpd.explorer.panels import ExplorerPanels, build_panels, teaching
from hkpd.explorer.panels.photo import NO_PERSON_CHOICE, PICKED_CHOICE
from hkpd.explorer.state import ExplorerState
from hkpd.kinematic_tree import body_joint_index


class RecordingActions:
    """Implements :class:`hkpd.explorer.panels.PanelActions`: the state is real, every other
    call is recorded as ``(name, *arguments)``."""

    def __init__(self) -> None:
        self.state = ExplorerState()
        self.state.set_image(400, 300)
        self.calls: list[tuple] = []

    def named(self, name: str) -> list[tuple]:
        return [call[1:] for call in self.calls if call[0] == name]

    def sampling_changed(self, changed: bool) -> None:
        self.calls.append(("sampling_changed", changed))

    def occluders_changed(self, changed: bool) -> bool:
        self.calls.append(("occluders_changed", changed))
        return changed

    def clear_occluders(self) -> None:
        self.calls.append(("clear_occluders",))

    def set_plain_drag_draws(self, enabled: bool) -> None:
        self.calls.append(("set_plain_drag_draws", enabled))

    def set_evidence(self, enabled: bool) -> None:
        self.calls.append(("set_evidence", enabled))

    def set_person_box(self, box) -> bool:
        self.calls.append(("set_person_box", box))
        return True

    def select_person(self, index: int) -> bool:
        self.calls.append(("select_person", index))
        return True

    def pick_person_next(self, enabled: bool = True) -> None:
        self.calls.append(("pick_person_next", enabled))

    def show_fit(self, visible: bool, opacity: float) -> None:
        self.calls.append(("show_fit", visible, opacity))

    def set_display_options(
        self, samples, heatmap, reprojection, heatmap_max_cm, colouring="log"
    ) -> bool:
        self.calls.append(
            ("set_display_options", samples, heatmap, reprojection, heatmap_max_cm, colouring)
        )
        return heatmap_max_cm != 10.0 or colouring != "log"

    def load_upload(self, name, content, client) -> None:
        self.calls.append(("load_upload", name, content))

    def add_same_person_upload(self, name, content, client) -> None:
        self.calls.append(("add_same_person_upload", name, content))

    def clear_same_person(self) -> None:
        self.calls.append(("clear_same_person",))

    def request_export(self, file_format: str, client) -> None:
        self.calls.append(("request_export", file_format))

    def request_screenshot(self, client) -> None:
        self.calls.append(("request_screenshot",))

    def request_page(self, client) -> None:
        self.calls.append(("request_page",))

    def save_scene(self, client) -> None:
        self.calls.append(("save_scene",))

    def load_scene_upload(self, name, content, client) -> None:
        self.calls.append(("load_scene_upload", name, content))

    def undo(self) -> bool:
        self.calls.append(("undo",))
        return True

    def redo(self) -> bool:
        self.calls.append(("redo",))
        return True

    def reset_everything(self) -> None:
        self.calls.append(("reset_everything",))

    def set_compare(self, setting) -> None:
        self.calls.append(("set_compare", setting))

    def compare_failed(self, message: str, client) -> None:
        self.calls.append(("compare_failed", message))


@pytest.fixture(scope="module")
def server():
    server = viser.ViserServer(port=0, verbose=False)
    yield server
    server.stop()


@pytest.fixture
def built(server) -> tuple[ExplorerPanels, RecordingActions]:
    server.gui.reset()
    actions = RecordingActions()
    return build_panels(server, actions), actions


def click(button: viser.GuiButtonHandle) -> None:
    button.value = True  # what a click does: a button's callbacks always run


def test_the_defaults_come_from_the_state(built) -> None:
    panels, actions = built
    assert panels.photo.evidence.value is True and not panels.photo.people.visible
    assert panels.samples.num_samples.value == actions.state.num_samples == 100
    assert panels.samples.num_displayed.value == 10 and panels.samples.seed.value == 0
    assert panels.teaching.joint.value == "left elbow"  # the menu shows names, not identifiers
    assert len(panels.concentration.joints) == 23
    assert panels.status.line.content == "Starting…"
    assert sorted(panels.export.meshes) == ["glb", "ply"]


def test_concentration_controls_change_the_state_and_reset_puts_them_back(built) -> None:
    panels, actions = built
    concentration = panels.concentration
    elbow = concentration.joints["left_elbow"]
    elbow.track.value = (-0.5,)  # a drag on the log track
    concentration.global_factor.box.value = 2.0  # typing 2 in the box means 2x
    concentration.shape_factor.track.value = (0.5,)
    snapshot = actions.state.snapshot()
    assert snapshot.joint_exponents[body_joint_index("left_elbow")] == -0.5
    assert snapshot.global_exponent == pytest.approx(math.log10(2.0), abs=1e-6)
    assert snapshot.shape_std_exponent == 0.5
    # The boxes hold the factor, in the unit their label states.
    assert elbow.box.label == "left elbow ×" and elbow.box.value == pytest.approx(10**-0.5)
    assert concentration.joints["right_knee"].box.value == 1.0
    assert concentration.shape_factor.box.value == pytest.approx(10**0.5)
    assert concentration.global_factor.track.value[0] == pytest.approx(math.log10(2.0))
    assert concentration.global_factor.box.value == 2.0  # the typed number stays as typed
    assert actions.named("sampling_changed") == [(True,)] * 3
    actions.calls.clear()
    click(concentration.reset_button)
    snapshot = actions.state.snapshot()
    assert not any(snapshot.joint_exponents) and snapshot.global_exponent == 0.0
    assert elbow.track.value == (0.0,) and elbow.box.value == 1.0
    assert concentration.shape_factor.box.value == 1.0
    assert actions.named("sampling_changed")[-1] == (True,)


def test_a_factor_box_typed_out_of_range_clips_the_state_not_the_box(built) -> None:
    panels, actions = built
    knee = panels.concentration.joints["left_knee"]
    knee.box.value = 0.0  # "0" typed on the way to "0.5": the box is left alone
    assert knee.box.value == 0.0 and knee.track.value == (-1.0,)
    assert actions.state.snapshot().joint_exponents[body_joint_index("left_knee")] == -1.0
    knee.box.value = 0.5
    assert knee.track.value[0] == pytest.approx(math.log10(0.5), abs=1e-6)
    knee.box.value = 25.0  # beyond 10x: the state stops at 10x
    assert actions.state.snapshot().joint_exponents[body_joint_index("left_knee")] == 1.0
    assert knee.box.value == 25.0  # the browser clamps the box when the user leaves it


def test_sample_controls_and_display_switches_reach_the_app(built) -> None:
    panels, actions = built
    samples = panels.samples
    samples.num_samples.value = 40
    samples.seed.value = 7
    assert actions.state.num_samples == 40 and actions.state.seed == 7
    click(samples.resample)
    assert actions.state.seed == 8 and samples.seed.value == 8
    legend = samples.legend.image.copy()
    assert not samples.heat_max.visible  # the log scale (default) has no top to move
    samples.colouring.value = COLOURINGS["linear"]
    assert samples.heat_max.visible
    samples.heat_max.value = 20.0
    assert actions.named("set_display_options")[-1] == (True, True, True, 20.0, "linear")
    assert not np.array_equal(samples.legend.image, legend)  # the colour bar was redrawn
    samples.show_samples.value = False
    assert actions.named("set_display_options")[-1] == (False, True, True, 20.0, "linear")
    linear = samples.legend.image.copy()
    samples.colouring.value = COLOURINGS["change"]
    assert actions.named("set_display_options")[-1][-1] == "change"
    assert not samples.heat_max.visible and not np.array_equal(samples.legend.image, linear)
    samples.fit_opacity.value = 0.3
    assert actions.named("show_fit")[-1] == (True, 0.3)


def test_photo_controls_and_the_person_menu(built) -> None:
    panels, actions = built
    photo = panels.photo
    photo.evidence.value = False
    photo.draw_mode.value = True
    assert actions.named("set_evidence") == [(False,)]
    assert actions.named("set_plain_drag_draws") == [(True,)]
    click(photo.pick)
    click(photo.forget)
    click(photo.clear)
    assert actions.named("pick_person_next") == [(True,)]
    assert actions.named("set_person_box") == [(None,)]
    assert actions.named("clear_occluders") == [()]
    photo.show_people(3)  # offering the people is not a choice
    assert photo.people.visible and len(photo.people.options) == 3
    assert actions.named("select_person") == []
    photo.people.value = photo.people.options[2]
    assert actions.named("select_person") == [(2,)]
    photo.show_people(1)
    assert not photo.people.visible and actions.named("select_person") == [(2,)]
    photo.show_people(3, None)  # a box the user picked: the menu says so, not "Person 3 of 3"
    assert photo.people.value == PICKED_CHOICE and photo.people.visible
    assert len(photo.people.options) == 4 and photo.chosen_person() is None
    photo.show_people(3, 1)
    assert photo.people.value.startswith("Person 2 of 3")
    photo.show_people(0, None)
    assert not photo.people.visible
    assert actions.named("select_person") == [(2,)]
    for count, choice in ((0, 0), (1, 0), (1, None), (2, 1), (0, None)):
        photo.show_people(count, choice)  # the value is always one of the entries
        assert photo.people.value in photo.people.options, (count, choice)
    # A browser's late echo of an older menu ("(one person)" before the user picked a box, seen
    # in the real-model browser test): not an entry now, so the menu goes back to "Your box".
    photo.people.value = NO_PERSON_CHOICE
    assert photo.people.value == PICKED_CHOICE
    assert actions.named("select_person") == [(2,)]


def test_each_occluder_has_working_controls(built) -> None:
    panels, actions = built
    occluder = actions.state.add_occluder((10, 20, 110, 220))
    snapshot = actions.state.snapshot()
    panels.photo.occluders.show(snapshot.occluders, snapshot.image_size)
    controls = panels.photo.occluders.controls(occluder.ident)
    assert [s.value for s in controls.corners] == [10.0, 20.0, 110.0, 220.0]
    assert [s.max for s in controls.corners] == [400.0, 300.0, 400.0, 300.0]
    controls.corners[2].value = 150.0
    assert actions.state.occluder(occluder.ident).box == (10.0, 20.0, 150.0, 220.0)
    # A box moved elsewhere (another tab, a drag) moves the sliders, same controls.
    actions.state.move_occluder(occluder.ident, (30, 20, 150, 220))
    panels.photo.occluders.show(actions.state.snapshot().occluders, (400, 300))
    assert panels.photo.occluders.controls(occluder.ident) is controls
    assert controls.corners[0].value == 30.0
    controls.enabled.value = False
    assert not actions.state.occluder(occluder.ident).enabled
    click(controls.delete)
    assert actions.state.snapshot().occluders == ()
    # move, toggle, delete (setting the sliders to the moved box is no edit: no call)
    assert actions.named("occluders_changed") == [(True,), (True,), (True,)]
    panels.photo.occluders.show((), (400, 300))
    with pytest.raises(KeyError):
        panels.photo.occluders.controls(occluder.ident)


def test_teaching_export_and_same_person(built) -> None:
    panels, actions = built
    assert "right knee" in panels.teaching.joint.options
    assert not any("_" in option for option in panels.teaching.joint.options)
    panels.teaching.joint.value = "right knee"
    assert actions.state.selected_joint == "right_knee"
    panels.teaching.show_teaching("right_knee", np.array([1234.5, 20.0, 3.0]), 2.0, [5, 1, 3])
    table = panels.teaching.axes_text.content
    assert "**right knee** (factor 2×)" in table and "| red | 1,234.5 | 1.0 |" in table
    assert "*network (sorted)*: the network's own concentrations" in table  # explained
    panels.teaching.show_teaching("right_knee", np.array([4.0, 2.0, 1.0]), 1.0)
    assert "network (sorted)" not in panels.teaching.axes_text.content
    help_text = teaching.EXPLANATION
    assert "white dots" not in help_text and "green" in help_text and "red" in help_text
    assert "adds the keypoints' evidence" not in help_text and "Laplace" in help_text
    panels.teaching.show_proxy(None)
    assert not panels.teaching.proxy_edges.visible
    click(panels.export.meshes["ply"])
    click(panels.export.screenshot)
    click(panels.export.page)
    click(panels.same_person.clear)
    assert actions.named("request_export") == [("ply",)]
    assert actions.named("request_screenshot") == [()]
    assert actions.named("request_page") == [()]
    assert actions.named("clear_same_person") == [()]
    panels.same_person.show("**2 photos**")
    assert panels.same_person.text.content == "**2 photos**"


class BrowserTab:
    """A browser tab as viser talks to it, for typing into the occluder fields without one.

    A typed value shows at once in the tab and reaches the server later, where viser's event
    loop (one thread, messages in order) stores it and runs the callbacks in its thread pool;
    every value the server assigns is shown in the tab when it arrives (here: at once). So a
    server write that crosses a typed value in flight leaves the tab showing the server's value.
    """

    def __init__(self, server: viser.ViserServer, seed: int) -> None:
        self.shown: dict[str, float] = {}
        self._rng = np.random.default_rng(seed)
        self._loop = ThreadPoolExecutor(1)
        self._pool = ThreadPoolExecutor(8)
        self._interface = server.gui._websock_interface
        self._queue_message = self._interface.queue_message

        def record(message, *args, **kwargs):
            if isinstance(message, GuiUpdateMessage) and "value" in message.updates:
                self.shown[message.uuid] = message.updates["value"]
            return self._queue_message(message, *args, **kwargs)

        self._interface.queue_message = record

    def type_and_enter(self, slider: viser.GuiSliderHandle, value: float) -> None:
        self.shown[slider._impl.uuid] = value
        self._loop.submit(self._arrive, slider, value, float(self._rng.uniform(0, 0.004)))

    def _arrive(self, slider: viser.GuiSliderHandle, value: float, delay_s: float) -> None:
        time.sleep(delay_s)
        if slider._impl.value == value:
            return
        slider._impl.value = value
        for callback in slider._impl.update_cb:
            self._pool.submit(callback, viser.GuiEvent(None, None, slider))

    def settle(self) -> None:
        self._loop.submit(lambda: None).result()
        self._pool.shutdown(wait=True)
        self._loop.shutdown(wait=True)
        self._interface.queue_message = self._queue_message

    def showing(self, slider: viser.GuiSliderHandle) -> float:
        return float(self.shown.get(slider._impl.uuid, slider.value))


class RedrawingActions(RecordingActions):
    """Like the app: a change redraws the occluder list from a snapshot of the state."""

    panels: ExplorerPanels

    def occluders_changed(self, changed: bool) -> bool:
        if changed:
            snapshot = self.state.snapshot()
            time.sleep(0.001)  # the scene is redrawn first, as in the app
            self.panels.photo.occluders.show(snapshot.occluders, snapshot.image_size)
        return changed


@pytest.mark.parametrize("seed", range(20))
def test_thirty_quick_edits_leave_the_fields_showing_the_box_in_use(server, seed) -> None:
    server.gui.reset()
    actions = RedrawingActions()
    actions.panels = build_panels(server, actions)
    occluder = actions.state.add_occluder((100, 60, 300, 240))
    actions.occluders_changed(True)
    corners = actions.panels.photo.occluders.controls(occluder.ident).corners
    tab, rng = BrowserTab(server, seed), np.random.default_rng(seed)
    ranges = ((0, 150), (0, 100), (200, 400), (150, 300))  # always a valid box
    for _ in range(30):
        corner = int(rng.integers(4))
        tab.type_and_enter(corners[corner], float(rng.integers(*ranges[corner])))
        time.sleep(float(rng.uniform(0, 0.003)))
    tab.settle()
    used = actions.state.occluder(occluder.ident).box
    assert tuple(slider.value for slider in corners) == used
    assert tuple(tab.showing(slider) for slider in corners) == used


def test_refused_and_reordered_edits_show_the_box_in_use(built) -> None:
    panels, actions = built
    occluder = actions.state.add_occluder((100, 60, 300, 240))
    snapshot = actions.state.snapshot()
    panels.photo.occluders.show(snapshot.occluders, snapshot.image_size)
    x0, _, x1, y1 = panels.photo.occluders.controls(occluder.ident).corners
    y1.value = 61.0  # a box one pixel tall is refused: the field goes back to the box in use
    assert actions.state.occluder(occluder.ident).box == (100.0, 60.0, 300.0, 240.0)
    assert y1.value == 240.0
    x0.value = 350.0  # past x1: the corners are swapped in the state and in the fields
    assert actions.state.occluder(occluder.ident).box == (300.0, 60.0, 350.0, 240.0)
    assert (x0.value, x1.value) == (300.0, 350.0)


def test_the_teaching_tab_shows_the_person_mask_and_what_the_shape_rests_on(built) -> None:
    panels, _ = built
    size = 32
    mask = np.zeros((size, size), np.float32)
    mask[8:24, 12:20] = 1.0
    known = np.ones((size, size), bool)
    known[:, :4] = False  # an occluder
    fit = SimpleNamespace(terms=("keypoints",))
    posterior = SimpleNamespace(
        network_input=SimpleNamespace(person_mask=mask, person_mask_known=known), evidence_fit=fit
    )
    proxy = torch.zeros(18, size, size)
    proxy[0, 0, 0] = 1.0
    panels.teaching.show_shape_basis(posterior, proxy)
    assert panels.teaching.person_mask.visible
    picture = panels.teaching.person_mask.image
    assert picture[16, 16, 2] > 200 and picture[16, 16, 0] < 100  # blue on the person
    assert tuple(picture[16, 1]) == tuple(teaching.UNKNOWN_COLOUR.astype(np.uint8))  # occluded
    text = panels.teaching.shape_text.content
    assert "keypoints in the fit" in text and "not used for the shape" in text
    fit.terms = ("keypoints", "silhouette")
    panels.teaching.show_shape_basis(posterior, proxy)
    assert "silhouette evidence" in panels.teaching.shape_text.content
    assert "not used" not in panels.teaching.shape_text.content
    reading = torch.zeros(19, size, size)  # an edges+mask network's input
    panels.teaching.show_shape_basis(posterior, reading)
    assert "keypoints and person mask" in panels.teaching.shape_text.content
    panels.teaching.show_proxy(reading)  # heatmaps are the last 17 channels
    none = SimpleNamespace(network_input=SimpleNamespace(person_mask=None, person_mask_known=None))
    panels.teaching.show_shape_basis(none, proxy)
    assert not panels.teaching.person_mask.visible
    assert "No person mask" in panels.teaching.shape_text.content


def test_the_person_mask_shows_the_mode_outline_and_its_iou(built) -> None:
    panels, _ = built
    size = 32
    mask = np.zeros((size, size), np.float32)
    mask[8:24, 12:20] = 1.0
    known = np.ones((size, size), bool)
    posterior = SimpleNamespace(
        network_input=SimpleNamespace(person_mask=mask, person_mask_known=known),
        evidence_fit=SimpleNamespace(terms=("keypoints", "silhouette")),
    )
    overlay = np.zeros((4 * size, 4 * size, 4), np.uint8)  # the render is finer than the crop
    overlay[32:96, 48:64, 3] = 255  # the body: rows 8-23, columns 12-15 of the crop
    panels.teaching.show_shape_basis(posterior, None, overlay)
    picture = panels.teaching.person_mask.image
    red = tuple(teaching.MODE_OUTLINE_COLOUR.astype(np.uint8))
    assert tuple(picture[8, 12]) == red and tuple(picture[16, 15]) == red  # on the outline
    assert tuple(picture[16, 13]) != red and tuple(picture[16, 18]) != red  # inside, beside
    assert "IoU 0.50" in panels.teaching.shape_text.content  # half the mask's width
    panels.teaching.show_shape_basis(posterior, None)  # no render: no outline, no IoU
    assert "IoU" not in panels.teaching.shape_text.content
    assert not (panels.teaching.person_mask.image == np.array(red, np.uint8)).all(-1).any()
