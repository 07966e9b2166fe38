"""The explorer in class, in a real headless Chromium (the harness of ``test_explorer_e2e``):
compare two settings side by side, save the scene, reset everything, undo, and reopen the saved
scene through the panel; type a factor in a concentration box; see the progress sign of a slow
prediction come and go; a photo without a person leaves no text of the last body; exports
download in one click. The app runs in-process with the test double (one app and one browser
page for the module), so the server state is checked directly. Skipped like
``test_explorer_e2e`` without playwright or /usr/bin/chromium."""

from __future__ import annotations

import io
import math
import re
import threading
import time

import numpy as np
import pytest
from PIL import Image
from test_explorer_e2e import (
    VIEWPORT,
    camera_settled,
    launch_chromium,
    playwright_api,
    wait_for,
    world_to_canvas,
)

from hkpd.explorer.compare import CompareSetting
from hkpd.explorer.progress import TITLE
from hkpd.explorer.scene import (
    BODY_POSITION,
    JOINT_LABEL_HEIGHT,
    LEGEND_HEIGHT,
    LEGEND_SIZE_M,
    LEGEND_Z,
)
from hkpd.explorer.scene_file import PhotoRef, parse_scene
from hkpd.kinematic_tree import body_joint_index
from hkpd.prediction.detection.keypoint_detector import NoPersonFoundError


class ClassroomDouble:
    """The test double, made slow (a loaded laptop) or blind (nobody in the photo) on demand."""

    def __init__(self) -> None:
        from test_explorer_double import OcclusionAwareDouble

        self.double = OcclusionAwareDouble()
        self.slow, self.blind = threading.Event(), threading.Event()

    def predict(self, image, occluders, evidence=True, bbox=None):
        if self.blind.is_set():
            raise NoPersonFoundError("photo: no person found")
        if self.slow.is_set():
            time.sleep(2.0)
        return self.double.predict(image, occluders, evidence, bbox)


@pytest.fixture(scope="module")
def app():
    from hkpd.explorer.app import ExplorerApp

    provider = ClassroomDouble()
    image = provider.double.scene.image
    explorer = ExplorerApp(provider, image, port=0, num_samples=30, num_displayed=2)
    explorer.classroom = provider
    yield explorer
    explorer.stop()


@pytest.fixture(scope="module")
def page(app):
    """One Chromium page on the app for the whole module."""
    with playwright_api.sync_playwright() as playwright:
        browser = launch_chromium(playwright)
        tab = browser.new_page(viewport=VIEWPORT, accept_downloads=True)
        tab.goto(app.url)
        wait_for(lambda: app.view is not None and app.server.get_clients(), what="first view")
        yield tab
        browser.close()


def test_compare_save_reset_undo_and_reopen_in_a_browser(app, page, tmp_path) -> None:
    photo = tmp_path / "demo.png"
    Image.fromarray(app._image).save(photo)
    app.keeper.photo = PhotoRef.of_file(photo)
    started = time.monotonic()
    app.add_occluder((250, 210, 300, 260))
    assert app.wait_idle(30)

    # Compare: Distribution › Compare › "B: without the boxes".
    page.get_by_role("tab", name="Distribution").click()
    page.get_by_text("Compare", exact=True).click()
    menu = page.locator("label", has_text="Compare with").first.get_attribute("for")
    page.locator(f"[id='{menu}']").click()
    page.get_by_role("option", name="B: without the boxes").click()
    wait_for(lambda: app.compare_columns.shown, what="B's columns")
    assert app.wait_idle(30) and app.compare.view is not None
    page.get_by_text("B ÷ A", exact=True).wait_for(timeout=20_000)  # the compare table

    # Save: one click downloads the scene.
    page.get_by_role("tab", name="Photo").click()
    with page.expect_download(timeout=30_000) as download:
        page.get_by_role("button", name="Save scene").click()
    saved = tmp_path / "scene.json"
    download.value.save_as(saved)
    scene = parse_scene(saved.read_text())
    assert scene.compare == "no-occluders" and len(scene.occluders) == 1

    # Reset everything, then Undo brings the boxes and the comparison back.
    page.get_by_role("button", name="Reset everything").click()
    wait_for(lambda: not app.state.snapshot().occluders and app.compare.setting is None,
             what="reset")  # fmt: skip
    assert app.wait_idle(30)
    page.get_by_text("Everything at its defaults.").wait_for(timeout=20_000)
    page.get_by_role("button", name="Undo").click()
    wait_for(lambda: app.compare.setting == CompareSetting("no-occluders"), what="undo")
    assert len(app.state.snapshot().occluders) == 1
    assert app.wait_idle(30)

    # Reset, then Load scene: the file the browser saved.
    page.get_by_role("button", name="Reset everything").click()
    wait_for(lambda: app.compare.setting is None, what="second reset")
    assert app.wait_idle(30)
    page.locator("input[type=file]").last.set_input_files(str(saved))
    wait_for(lambda: app.compare.setting is not None, what="the loaded scene")
    assert app.wait_idle(30)
    assert len(app.state.snapshot().occluders) == 1 and app.compare_columns.shown
    page.get_by_text("Not default:").wait_for(timeout=20_000)
    assert not app.errors, app.errors
    assert time.monotonic() - started < 120


def test_a_concentration_box_takes_the_factor_typed_in_it(app, page) -> None:
    app.reset_everything()
    assert app.wait_idle(30)
    knee = body_joint_index("left_knee")
    page.get_by_role("tab", name="Distribution").click()
    page.get_by_text("Left leg", exact=True).click()
    box_id = page.locator("label", has_text="left knee ×").first.get_attribute("for")
    box = page.locator(f"[id='{box_id}']")
    box.scroll_into_view_if_needed()

    def type_factor(text: str, factor: float) -> None:
        box.click()
        box.press("Control+a")
        box.press_sequentially(text, delay=80)  # key by key, as a user types
        wait_for(
            lambda: abs(app.state.snapshot().joint_exponents[knee] - math.log10(factor)) < 1e-6,
            what=f"{factor}x in the state",
        )
        assert app.wait_idle(30)
        snapshot = app.state.snapshot()
        assert snapshot.concentration_factors[knee] == pytest.approx(factor, rel=1e-5)
        assert app.view.sampling_version == snapshot.sampling_version  # drawn with it
        assert box.input_value() == text  # the box keeps what was typed, in its unit

    type_factor("2", 2.0)
    type_factor("0.5", 0.5)  # its "0" on the way does not jump to 0.1 under the cursor
    assert "left knee 0.5×" in app.panels.keep.changes.content
    assert not app.errors, app.errors


def test_a_slow_prediction_shows_its_progress_until_the_view_is_drawn(app, page) -> None:
    app.classroom.slow.set()  # each prediction takes 2 s more
    try:
        app.add_occluder((300, 100, 340, 140))
        wait_for(lambda: app.progress.text.startswith("Predicting the posterior (1 of 3)"),
                 what="the first stage")  # fmt: skip
        page.get_by_text(TITLE, exact=True).wait_for(timeout=10_000)  # the notification
        # Its stage, "Predicting the posterior (1 of 3)…" (the next ones by the time a loaded
        # machine has drawn it).
        page.get_by_text(re.compile(r"\([123] of 3\)…")).first.wait_for(timeout=5_000)
        assert app.wait_idle(30)
    finally:
        app.classroom.slow.clear()
    page.get_by_text(TITLE, exact=True).wait_for(state="detached", timeout=10_000)
    assert page.get_by_text("Predicting the posterior").count() == 0
    assert app.panels.status.line.content.startswith("Prediction ")  # the timings again


def png_upload(image: np.ndarray, name: str) -> dict:
    buffer = io.BytesIO()
    Image.fromarray(image).save(buffer, format="PNG")
    return {"name": name, "mimeType": "image/png", "buffer": buffer.getvalue()}


def drawn_under_the_bodies(app, page) -> tuple[int, int]:
    """Dark or coloured pixels of a screenshot where the arrows' line (under the middle body)
    and the colour bar (under the uncertainty body) are drawn: ``(line, bar)``."""
    shot = np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB")).astype(int)
    drawn = (255 - shot).max(axis=2) > 60
    counts = []
    for x, y, half_width, half_height in (
        (BODY_POSITION[0], JOINT_LABEL_HEIGHT - 0.05, 0.5, 0.05),
        (app.scene.layout.heat_x, LEGEND_HEIGHT, LEGEND_SIZE_M[0] / 2, LEGEND_SIZE_M[1] / 2),
    ):
        corners = np.array([[x - half_width, y + half_height, LEGEND_Z],
                            [x + half_width, y - half_height, LEGEND_Z]])  # fmt: skip
        (left, top), (right, bottom) = world_to_canvas(app, corners, page).round().astype(int)
        counts.append(int(drawn[max(top, 0) : bottom, max(left, 0) : right].sum()))
    return counts[0], counts[1]


def test_no_person_leaves_no_text_of_the_last_body(app, page) -> None:
    nodes = app.server.scene._handle_from_node_name
    assert "/legend" in nodes and "/joint_axes_label" in nodes
    time.sleep(2.0)  # the last view has faded in
    line, bar = drawn_under_the_bodies(app, page)
    assert line > 100 and bar > 1000, (line, bar)
    page.get_by_role("tab", name="Photo").click()
    upload = page.locator("input[type=file]").first
    app.classroom.blind.set()
    try:
        upload.set_input_files(files=[png_upload(np.full((256, 192, 3), 200, np.uint8), "x.png")])
        wait_for(lambda: app.state.image_size == (192, 256) and app.view is None,
                 what="the photo without a person")  # fmt: skip
        assert app.wait_idle(30)
    finally:
        app.classroom.blind.clear()
    page.get_by_text("No person was found", exact=False).first.wait_for(timeout=10_000)
    camera_settled(app)  # the new photo is framed
    time.sleep(1.0)
    assert "/legend" not in nodes and "/joint_axes_label" not in nodes
    line_after, bar_after = drawn_under_the_bodies(app, page)
    assert line_after < 0.1 * line and bar_after < 0.05 * bar, (line_after, bar_after)
    assert "Network only." not in page.inner_text("body")  # the last person's source line
    assert app.panels.teaching.axes_text.content == ""
    # The first photo again, for the tests after this one.
    upload.set_input_files(files=[png_upload(app.classroom.double.scene.image, "demo.png")])
    wait_for(lambda: app.view is not None, what="the person again")
    assert app.wait_idle(30)


def test_exports_download_in_one_click(app, page) -> None:
    page.get_by_role("tab", name="Distribution").click()
    page.get_by_text("Export", exact=True).click()
    with page.expect_download(timeout=30_000) as download:
        page.get_by_role("button", name="Meshes (GLB)").click()
    assert download.value.suggested_filename == "hkpd_bodies.glb"
    with open(download.value.path(), "rb") as glb:
        assert glb.read(4) == b"glTF"
    with page.expect_download(timeout=60_000) as download:
        page.get_by_role("button", name="Export page (HTML)").click()
    assert download.value.suggested_filename == "hkpd_scene.html"
    with open(download.value.path(), encoding="utf-8") as html:
        assert "<html" in html.read(4000).lower()
    assert not app.errors, app.errors
