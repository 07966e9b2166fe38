"""The explorer app without a browser: the server runs in-process on the demo photo, driven by
the test double of the predictor (see ``test_explorer_double.py``), and the CLI as a subprocess.
"""

from __future__ import annotations

import io
import os
import re
import signal
import subprocess
import sys
import threading
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
import trimesh
from PIL import Image
from test_explorer_double import COCO, OcclusionAwareDouble

from hkpd.explorer.app import ExplorerApp
from hkpd.explorer.posterior_view import part_uncertainty

ROOT = Path(__file__).resolve().parents[1]
EXPLORE = [sys.executable, "-m", "hkpd.explorer.cli"]


class RecordingClient:
    """Stands in for a viser ClientHandle: records notifications and downloads."""

    def __init__(self) -> None:
        self.notifications: list[tuple[str, str]] = []
        self.downloads: dict[str, bytes] = {}

    def add_notification(self, title: str, body: str, **_kwargs) -> None:
        self.notifications.append((title, body))

    def send_file_download(self, name: str, content: bytes, save_immediately=False) -> None:
        self.downloads[name] = content
        self.saved_at_once = save_immediately  # one click downloads (no link to click)


@pytest.fixture(scope="module")
def app():
    double = OcclusionAwareDouble()
    explorer = ExplorerApp(double, double.scene.image, port=0, num_displayed=3)
    explorer.double = double
    assert explorer.wait_idle(60)
    yield explorer
    explorer.stop()


def limb_uncertainty(app, parts: tuple[str, ...]) -> float:
    values = part_uncertainty(app.view.uncertainty, app.double.body.part_labels.numpy())
    return float(np.mean([values[p] for p in parts]))


def test_first_view_is_drawn_with_the_requested_counts(app):
    view = app.view
    assert view is not None and not app.errors
    assert view.sample_vertices.shape == (3, 13492, 3)
    assert view.sample_keypoints2d.shape == (100, 17, 2)
    assert view.uncertainty.shape == (13492,) and np.all(view.uncertainty >= 0)
    assert app.scene.placement is not None


def test_occluding_an_ankle_raises_uncertainty_of_that_foot_only(app):
    ankle = app.double.scene.keypoints2d[COCO.index("right_ankle")]
    leg = ("right_ankle", "right_foot")
    other = ("left_ankle", "left_foot")
    before_leg, before_other = limb_uncertainty(app, leg), limb_uncertainty(app, other)
    assert app.add_occluder((ankle[0] - 20, ankle[1] - 20, ankle[0] + 20, ankle[1] + 20))
    assert app.wait_idle(30)
    assert app.result.posterior.confidences[COCO.index("right_ankle")] < 0.5
    assert limb_uncertainty(app, leg) > 1.5 * before_leg
    assert limb_uncertainty(app, other) == pytest.approx(before_other, rel=0.25)
    # Switching it off restores the prediction.
    ident = app.state.snapshot().occluders[0].ident
    app.occluders_changed(app.state.set_occluder_enabled(ident, False))
    assert app.wait_idle(30)
    assert limb_uncertainty(app, leg) == pytest.approx(before_leg, rel=0.25)
    app.clear_occluders()
    assert app.wait_idle(30)


def test_concentration_slider_changes_only_the_sampling(app):
    calls = app.double.calls
    before = limb_uncertainty(app, ("left_knee",))
    app.sampling_changed(app.state.set_joint_exponent("left_hip", -1.0))
    assert app.wait_idle(30)
    assert app.double.calls == calls  # no new prediction for a concentration change
    assert limb_uncertainty(app, ("left_knee",)) > 2 * before
    assert app.view.axes.joint == app.state.selected_joint
    app.sampling_changed(app.state.reset_concentrations())
    assert app.wait_idle(30)


def test_bad_upload_keeps_the_current_photo_and_says_why(app):
    client = RecordingClient()
    size = app.state.image_size
    app.load_upload("holiday.gif.exe", b"MZ....", client)
    app.load_upload("broken.jpg", b"\xff\xd8\xff\xe0 not really", client)
    assert app.wait_idle(30)
    assert app.state.image_size == size
    assert [title for title, _ in client.notifications] == ["Photo not loaded"] * 2
    assert "not a supported photo" in client.notifications[0][1]


def test_good_upload_replaces_the_photo_and_clears_occluders(app):
    client = RecordingClient()
    app.add_occluder((10, 10, 60, 60))
    buffer = io.BytesIO()
    Image.fromarray(np.full((300, 200, 3), 90, np.uint8)).save(buffer, format="JPEG")
    app.load_upload("person.jpg", buffer.getvalue(), client)
    assert app.wait_idle(30)
    assert app.state.image_size == (200, 300)
    assert app.state.snapshot().occluders == ()
    assert client.notifications[-1][0] == "Photo loaded"
    assert app.scene.placement.width_px == 200


def test_export_sends_the_mode_and_samples(app):
    client = RecordingClient()
    app.request_export("glb", client)
    assert app.wait_idle(30)
    scene = trimesh.load(io.BytesIO(client.downloads["hkpd_bodies.glb"]), file_type="glb")
    assert len(scene.geometry) == 1 + len(app.view.sample_vertices)
    assert client.saved_at_once  # one click: the browser saves it, no link to click again


class NoPersonProvider:
    """A provider that fails the way a predictor does on a photo without a person."""

    def predict(self, image, occluders, evidence=True, bbox=None):
        raise ValueError("no person found in the photo")


class FindsNobodyUnlessBoxed:
    """Raises the detector's NoPersonFoundError until given a person box; records calls."""

    def __init__(self) -> None:
        self.double = OcclusionAwareDouble()
        self.calls: list[tuple[bool, object]] = []

    def predict(self, image, occluders, evidence=True, bbox=None):
        from hkpd.prediction.detection.keypoint_detector import NoPersonFoundError

        self.calls.append((evidence, bbox))
        if bbox is None:
            raise NoPersonFoundError("photo: no person found")
        return self.double.predict(image, occluders, evidence, bbox)


def test_no_person_says_how_to_pick_one_and_a_person_box_predicts_there():
    provider = FindsNobodyUnlessBoxed()
    explorer = ExplorerApp(provider, provider.double.scene.image, port=0)
    try:
        assert explorer.wait_idle(30)
        assert "Pick the person" in explorer.panels.status.line.content and explorer.view is None
        assert not explorer.errors  # an expected situation, not a failure
        assert explorer.set_person_box((20, 20, 300, 500))
        assert explorer.wait_idle(30)
        assert provider.calls[-1] == (True, (20.0, 20.0, 300.0, 500.0))
        assert explorer.view is not None
        explorer.set_evidence(False)
        assert explorer.wait_idle(30)
        assert provider.calls[-1][0] is False
    finally:
        explorer.stop()


def test_a_failing_prediction_is_reported_and_the_server_keeps_running():
    image = np.full((120, 90, 3), 200, np.uint8)
    explorer = ExplorerApp(NoPersonProvider(), image, port=0)
    try:
        assert explorer.wait_idle(30)
        assert explorer.errors and "no person found" in explorer.errors[0]
        assert "no person found" in explorer.panels.status.line.content
        assert explorer.add_occluder((10, 10, 40, 40))  # still responsive
        assert explorer.wait_idle(30)
        assert len(explorer.errors) == 2 and explorer.view is None
    finally:
        explorer.stop()


def run_cli(*args: str, timeout: float = 60) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT / "tests")}
    return subprocess.run(
        [*EXPLORE, *args], capture_output=True, text=True, timeout=timeout, env=env
    )


def test_cli_missing_image_fails_clearly_without_traceback():
    result = run_cli("/no/such/photo.jpg", "--no-browser")
    assert result.returncode != 0
    assert "photo.jpg" in result.stderr and "Traceback" not in result.stderr


def test_the_shipped_photo_is_the_installed_cc0_photo() -> None:
    from hkpd.explorer.demo_photo import shipped_photo

    path = shipped_photo()
    assert path.name == "warrior_lunge.jpg" and path.is_file()
    assert "warrior_lunge.jpg" in (path.parent / "NOTICE.md").read_text()  # its licence
    with Image.open(path) as photo:
        assert photo.size == (1080, 720)


def test_cli_serves_the_demo_and_stops_cleanly_on_ctrl_c():
    env = {**os.environ, "PYTHONPATH": str(ROOT / "tests")}
    process = subprocess.Popen(
        [
            *EXPLORE,
            "--no-browser",
            "--port",
            "0",
            "--host",
            "0.0.0.0",
            "--provider",
            "test_explorer_double:OcclusionAwareDouble",
            "--demo",
            "synthetic",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    try:
        deadline = time.monotonic() + 60
        line = ""
        while "running at" not in line and time.monotonic() < deadline:
            line = process.stdout.readline()
        assert "running at http://" in line
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 130, err  # Ctrl-C: exit 130 at any moment, also while serving
    assert "stopping" in out and "Traceback" not in err
    assert "hkpd-explore: interrupted; stopped" in err
    assert "warning: binding to 0.0.0.0" in err


def test_a_new_photo_takes_the_old_photos_occluders_away(app):
    """Occluders belong to their photo: none stays drawn (or listed) after a new one loads."""
    scene = app.double.scene
    assert app.add_occluder((10, 10, 60, 60))
    assert app.wait_idle(30)
    names = app.server.scene._handle_from_node_name
    assert any(name.startswith("/photo/occluders/") for name in names)
    client = RecordingClient()
    app._image_job(scene.image[:, ::-1].copy(), "mirrored.png", client)
    assert app.wait_idle(30)
    assert app.state.snapshot().occluders == ()
    assert not [n for n in app.server.scene._handle_from_node_name if "/occluders/" in n]
    assert ("Photo loaded", "mirrored.png") in client.notifications
    app._image_job(scene.image, "demo.png", client)  # back to the first photo for later tests
    assert app.wait_idle(30)


def test_the_fit_overlay_is_drawn_on_the_photo_and_can_be_hidden(app):
    assert app._overlay is not None
    assert "/photo/fit" in app.server.scene._handle_from_node_name
    app.show_fit(False, 0.5)
    assert "/photo/fit" not in app.server.scene._handle_from_node_name
    app.show_fit(True, 0.5)
    assert "/photo/fit" in app.server.scene._handle_from_node_name


class TwoPeopleProvider:
    """The test double, plus a person finder that reports two people."""

    BOXES = ((10.0, 20.0, 200.0, 460.0), (220.0, 30.0, 380.0, 470.0))

    def __init__(self) -> None:
        self.double = OcclusionAwareDouble()
        self.calls: list[object] = []

    def predict(self, image, occluders, evidence=True, bbox=None):
        self.calls.append(bbox)
        return self.double.predict(image, occluders, evidence, bbox)

    def find_people(self, image) -> list[tuple[float, float, float, float]]:
        return list(self.BOXES)


def test_several_people_are_offered_and_choosing_one_predicts_inside_its_box():
    provider = TwoPeopleProvider()
    explorer = ExplorerApp(provider, provider.double.scene.image, port=0, num_displayed=2)
    try:
        assert explorer.wait_idle(60)
        assert explorer.people == TwoPeopleProvider.BOXES
        dropdown = explorer.panels.photo.people
        assert dropdown.visible and len(dropdown.options) == 2
        assert dropdown.value.startswith("Person 1 of 2")
        assert provider.calls == [None]  # showing the choice predicted nothing more
        dropdown.value = dropdown.options[1]  # as the user's choice arrives
        assert explorer.wait_idle(30)
        assert provider.calls[-1] == TwoPeopleProvider.BOXES[1]
        assert explorer.state.snapshot().person_box == TwoPeopleProvider.BOXES[1]
        assert not explorer.select_person(2) and not explorer.errors
    finally:
        explorer.stop()


def test_one_person_or_no_finder_hides_the_choice(app):
    assert app.people == () and not app.panels.photo.people.visible


def test_pick_the_person_says_to_drag_a_box(app):
    assert app.wait_idle(30)  # no job left to overwrite the status line
    app.panels.photo.pick.value = True  # its callbacks run, as for a click in the browser
    try:
        assert "Drag a box around the person" in app.panels.status.line.content
    finally:
        app.pick_person_next(False)


def test_a_silhouette_model_is_refused_at_start(tmp_path) -> None:
    import torch

    from hkpd.explorer.provider import PredictorProvider
    from hkpd.network import DistributionNetwork
    from hkpd.network.checkpoint import save_checkpoint
    from hkpd.network.config import NetworkConfig

    config = NetworkConfig(backbone_base_width=8, image_size=64, image_proxy="silhouette")
    torch.manual_seed(0)
    model = save_checkpoint(
        tmp_path / "silhouette.pt", DistributionNetwork(config), config.to_dict(), 0, {}, 0
    )
    with pytest.raises(ValueError, match="no person segmentation"):
        PredictorProvider(model, device="cpu")


def test_the_status_says_which_distribution_and_whether_it_was_read_upright() -> None:
    from types import SimpleNamespace

    from hkpd.explorer.panels.status import source_text

    fit = SimpleNamespace(evidence_count=15, seconds=0.043)
    conditioned = SimpleNamespace(
        fallback_reason=None, conditioned=True, evidence_fit=fit, upright_tilt_degrees=None
    )
    assert source_text(conditioned) == "*Conditioned on 15 keypoints (fit 43 ms).*"
    lying = SimpleNamespace(fallback_reason=None, conditioned=False, upright_tilt_degrees=-87.4)
    assert "Network only." in source_text(lying) and "leans 87°" in source_text(lying)
    fallback = SimpleNamespace(fallback_reason="only 2 keypoints", upright_tilt_degrees=None)
    assert source_text(fallback) == "*Network only: only 2 keypoints.*"
    mirrored = SimpleNamespace(
        fallback_reason=None, conditioned=False, upright_tilt_degrees=None, mirror_read=True
    )
    assert "flipped left to right" in source_text(mirrored)
    assert "flipped" not in source_text(lying)


def test_class_facing_text_names_no_internal_flag() -> None:
    """Issue 58: the status line (and so the page caption) says each quality flag in words,
    never its name (``turned_copy``, ``cut_off_by_edge`` ...), and the PNG's photo title is the
    live app's (no "shift+drag" hint left in a screenshot)."""
    from types import SimpleNamespace

    from hkpd.explorer.html_page import static_text
    from hkpd.explorer.panels.status import source_text
    from hkpd.explorer.scene import column_titles
    from hkpd.prediction.quality import FLAG_MEANINGS, ReadingQuality

    for flags in (("cut_off_by_edge", "turned_copy"), ("small_person", "off_centre_in_box"),
                  tuple(FLAG_MEANINGS)):  # fmt: skip
        for score in (0.9, 0.3):
            posterior = SimpleNamespace(
                fallback_reason=None, conditioned=False, upright_tilt_degrees=12.0,
                mirror_read=True, quality=ReadingQuality(score, flags, {}),
            )  # fmt: skip
            for text in (source_text(posterior), static_text(source_text(posterior))):
                assert not re.search(r"\b[a-z]+_[a-z_]+\b|\w\(\)", text), text
                assert "mirror image" not in text
                assert FLAG_MEANINGS[flags[0]] in text
    assert column_titles("log", static=False) == column_titles("log", static=True)
    assert "shift" not in column_titles("log")[0].lower()


def change_ratio(app, parts: tuple[str, ...]) -> float:
    values = part_uncertainty(app.view.change_ratio, app.double.body.part_labels.numpy())
    return float(np.mean([values[p] for p in parts]))


def test_the_change_colouring_shows_an_occluded_foot_against_the_same_photo_without_it(app):
    predictions = app.double.calls
    assert app.set_display_options(True, True, True, 10.0, "change")
    assert app.wait_idle(30)
    # No occluder: the view is its own baseline (same seed and sample count): ratio 1.
    np.testing.assert_allclose(app.view.change_ratio, 1.0, rtol=1e-5)
    assert app.scene.legend_scale.kind == "change"
    ankle = app.double.scene.keypoints2d[COCO.index("right_ankle")]
    assert app.add_occluder((ankle[0] - 20, ankle[1] - 20, ankle[0] + 20, ankle[1] + 20))
    assert app.wait_idle(30)
    assert change_ratio(app, ("right_ankle", "right_foot")) > 1.5
    assert change_ratio(app, ("left_ankle", "left_foot")) == pytest.approx(1.0, abs=0.25)
    # The baseline was the first prediction of this photo: one new prediction (the occluder).
    assert app.double.calls == predictions + 1
    # The colours follow the ratio: the hidden foot is redder than the other one.
    colours = app.scene._heat_points.colors.astype(float)
    labels = app.double.body.part_labels.numpy()
    red = colours[:, 0] - colours[:, 2]
    assert red[labels == 8].mean() > red[labels == 7].mean() + 40  # right vs left ankle
    app.clear_occluders()
    assert app.set_display_options(True, True, True, 10.0, "log")
    assert app.wait_idle(30)
    assert app.scene.legend_scale.kind == "log"


def test_the_change_colouring_predicts_a_missing_baseline_once(app):
    ankle = app.double.scene.keypoints2d[COCO.index("right_ankle")]
    app.add_occluder((ankle[0] - 20, ankle[1] - 20, ankle[0] + 20, ankle[1] + 20))
    app.set_person_box((5.0, 5.0, *app.state.image_size))  # a new person box, occluded
    assert app.wait_idle(30)
    predictions = app.double.calls
    app.set_display_options(True, True, True, 10.0, "change")
    assert app.wait_idle(30)
    assert app.double.calls == predictions + 1  # the baseline of the new box
    # > 1: the baseline was predicted without the occluder (with it, the ratio would be 1).
    assert change_ratio(app, ("right_ankle", "right_foot")) > 1.5
    app.sampling_changed(app.state.set_joint_exponent("left_hip", -1.0))
    assert app.wait_idle(30)
    assert app.double.calls == predictions + 1  # cached: no prediction for a slider
    assert change_ratio(app, ("left_knee",)) > 2.0  # the concentration change shows too
    app.sampling_changed(app.state.reset_concentrations())
    app.clear_occluders()
    app.set_person_box(None)
    app.set_display_options(True, True, True, 10.0, "log")
    assert app.wait_idle(30)


def test_the_floor_is_behind_the_photo_and_the_colour_bar(app):
    """Seen from the framed camera a floor in front of the photo plane was drawn over the
    photo's bottom and across the colour bar: it must lie behind both, right of the photo."""
    from hkpd.explorer.scene import FLOOR_HEIGHT, LEGEND_HEIGHT, LEGEND_SIZE_M, LEGEND_Z

    floor = app.server.scene._handle_from_node_name["/floor"]
    placement = app.scene.placement
    front = floor.position[2] + floor.height / 2
    assert front <= 0.0 < LEGEND_Z  # photo plane z = 0, colour bar in front of it
    assert floor.position[0] - floor.width / 2 >= placement.centre[0] - placement.width_m / 2
    assert LEGEND_HEIGHT + LEGEND_SIZE_M[1] / 2 < FLOOR_HEIGHT  # the bar is under the floor


def test_reprojected_skeletons_stay_on_the_photo(app):
    from hkpd.explorer.scene import clip_segments

    segments = app.server.scene._handle_from_node_name["/photo/reprojection"].points
    placement = app.scene.placement
    half = np.array([placement.width_m, placement.height_m]) / 2 + 1e-6
    assert np.all(np.abs(segments[..., :2]) <= half)
    clipped = clip_segments(np.array([[[-50.0, 10.0], [50.0, 10.0]], [[-9, -9], [-1, -1]]]),
                            (20, 30))  # fmt: skip
    np.testing.assert_allclose(clipped[0], [[0.0, 10.0], [20.0, 10.0]])
    np.testing.assert_allclose(clipped[1, 0], clipped[1, 1])  # outside: nothing drawn


def test_the_joint_label_is_under_the_mode_body_not_on_the_uncertainty_body(app):
    from hkpd.explorer.scene import HEATMAP_OFFSET

    label = app.server.scene._handle_from_node_name["/joint_axes_label"]
    lowest = -app.view.mode_vertices[:, 1].max()  # body frame y down -> world
    assert label.position[1] < lowest and abs(label.position[0]) < HEATMAP_OFFSET / 4
    assert "left elbow" in label.text and "_" not in label.text


def test_bombs_and_huge_uploads_at_once_are_refused_with_a_message(app):
    from test_prediction_image_input import png_header_only

    client = RecordingClient()
    size = app.state.image_size
    uploads = [("bomb.png", png_header_only(30000, 30000))]
    uploads += [(f"huge_{i}.png", png_header_only(13300, 13300)) for i in range(3)]
    buffer = io.BytesIO()
    Image.fromarray(np.random.default_rng(0).integers(0, 255, (300, 400, 3), np.uint8)).save(
        buffer, format="JPEG"
    )
    uploads += [("cut.jpg", buffer.getvalue()[: len(buffer.getvalue()) // 2])]  # truncated
    threads = [
        threading.Thread(target=app.load_upload, args=(name, content, client))
        for name, content in uploads
    ]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert app.wait_idle(30)
    assert app.state.image_size == size
    assert [title for title, _ in client.notifications] == ["Photo not loaded"] * 5
    messages = sorted(message for _, message in client.notifications)
    assert all("megapixels" in message for message in messages if "huge" in message)
    assert "megapixels" in next(m for m in messages if "bomb" in m)
    assert "could not be read" in next(m for m in messages if "cut" in m)


def test_a_busy_port_is_an_error_naming_it_and_suggesting_port_0():
    import socket

    with socket.create_server(("127.0.0.1", 0)) as taken:
        port = taken.getsockname()[1]
        result = run_cli("--no-browser", "--port", str(port), "--demo", "synthetic",
                         "--provider", "test_explorer_double:OcclusionAwareDouble")  # fmt: skip
    assert result.returncode != 0
    assert f"port {port} is already in use" in result.stderr and "--port 0" in result.stderr
    assert "Traceback" not in result.stderr and "running at" not in result.stdout


def test_removing_occluders_warns_nothing_and_remove_all_numbers_from_one(app):
    app.clear_occluders()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for offset in (0, 60, 120):
            assert app.add_occluder((10 + offset, 10, 50 + offset, 50))
        first = app.state.snapshot().occluders[0].ident
        app.occluders_changed(app.state.set_occluder_enabled(first, False))
        click = app.panels.photo.occluders.controls(first).delete
        click.value = True  # the Delete button
        app.clear_occluders()  # "Remove all occluders"
        assert app.add_occluder((10, 10, 50, 50))
        assert app.wait_idle(30)
        app.clear_occluders()
        assert app.wait_idle(30)
    removal = [str(w.message) for w in caught if "already removed" in str(w.message)]
    assert removal == []
    assert app.add_occluder((10, 10, 50, 50))
    assert [o.ident for o in app.state.snapshot().occluders] == [1]
    assert app.panels.photo.occluders.controls(1).folder.label == "Occluder #1"
    app.clear_occluders()


def test_cli_refuses_a_startup_photo_over_the_pixel_limit(tmp_path):
    from test_prediction_image_input import png_header_only

    photo = tmp_path / "huge.png"
    photo.write_bytes(png_header_only(13300, 13300))
    result = run_cli(str(photo), "--no-browser", "--port", "0")
    assert result.returncode != 0 and "Traceback" not in result.stderr
    assert "13300x13300" in result.stderr and "megapixels" in result.stderr
