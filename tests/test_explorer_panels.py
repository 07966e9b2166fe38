"""The panel's sections without a browser: each builder wired to a recording stand-in for the
app, each control driven server-side (viser runs a handle's callbacks when the server assigns
its value, as when a browser does)."""

from __future__ import annotations

import numpy as np
import pytest
import viser

from hkpd.explorer.panels import ExplorerPanels, build_panels
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

    def set_display_options(self, samples, heatmap, reprojection, heatmap_max_cm) -> bool:
        self.calls.append(("set_display_options", samples, heatmap, reprojection, heatmap_max_cm))
        return heatmap_max_cm != 10.0

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
    assert panels.teaching.joint.value == "left_elbow"
    assert len(panels.concentration.joint_sliders) == 23
    assert panels.status.line.content == "Starting…"
    assert sorted(panels.export.meshes) == ["glb", "ply"]


def test_concentration_sliders_change_the_state_and_reset_puts_them_back(built) -> None:
    panels, actions = built
    concentration = panels.concentration
    concentration.joint_sliders["left_elbow"].value = -0.5
    concentration.global_slider.value = 0.25
    concentration.shape_slider.value = 0.5
    snapshot = actions.state.snapshot()
    assert snapshot.joint_exponents[body_joint_index("left_elbow")] == -0.5
    assert snapshot.global_exponent == 0.25 and snapshot.shape_std_exponent == 0.5
    assert actions.named("sampling_changed") == [(True,)] * 3
    actions.calls.clear()
    click(concentration.reset_button)
    snapshot = actions.state.snapshot()
    assert not any(snapshot.joint_exponents) and snapshot.global_exponent == 0.0
    assert concentration.joint_sliders["left_elbow"].value == 0.0
    assert concentration.shape_slider.value == 0.0
    assert actions.named("sampling_changed")[-1] == (True,)


def test_sample_controls_and_display_switches_reach_the_app(built) -> None:
    panels, actions = built
    samples = panels.samples
    samples.num_samples.value = 40
    samples.seed.value = 7
    assert actions.state.num_samples == 40 and actions.state.seed == 7
    click(samples.resample)
    assert actions.state.seed == 8 and samples.seed.value == 8
    legend = samples.legend.image.copy()
    samples.heat_max.value = 20.0
    assert actions.named("set_display_options")[-1] == (True, True, True, 20.0)
    assert not np.array_equal(samples.legend.image, legend)  # the colour bar was redrawn
    samples.show_samples.value = False
    assert actions.named("set_display_options")[-1] == (False, True, True, 20.0)
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
    # move, the moved slider's echo (nothing changes: the state has that box), toggle, delete
    assert actions.named("occluders_changed") == [(True,), (False,), (True,), (True,)]
    panels.photo.occluders.show((), (400, 300))
    with pytest.raises(KeyError):
        panels.photo.occluders.controls(occluder.ident)


def test_teaching_export_and_same_person(built) -> None:
    panels, actions = built
    panels.teaching.joint.value = "right_knee"
    assert actions.state.selected_joint == "right_knee"
    panels.teaching.show_teaching("right_knee", np.array([1234.5, 20.0, 3.0]), 2.0, [5, 1, 3])
    table = panels.teaching.axes_text.content
    assert "**right knee** (factor 2×)" in table and "| red | 1,234.5 | 1.0 |" in table
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
