"""The explorer in class, in a real headless Chromium (the harness of ``test_explorer_e2e``):
compare two settings side by side, save the scene, reset everything, undo, and reopen the saved
scene through the panel. The app runs in-process with the test double, so the server state is
checked directly. Skipped like ``test_explorer_e2e`` without playwright or /usr/bin/chromium."""

from __future__ import annotations

import time

import pytest
from PIL import Image
from test_explorer_e2e import VIEWPORT, launch_chromium, playwright_api, wait_for

from hkpd.explorer.compare import CompareSetting
from hkpd.explorer.scene_file import PhotoRef, parse_scene


@pytest.fixture(scope="module")
def app():
    from test_explorer_double import OcclusionAwareDouble

    from hkpd.explorer.app import ExplorerApp

    double = OcclusionAwareDouble()
    explorer = ExplorerApp(double, double.scene.image, port=0, num_samples=30, num_displayed=2)
    yield explorer
    explorer.stop()


def test_compare_save_reset_undo_and_reopen_in_a_browser(app, tmp_path) -> None:
    photo = tmp_path / "demo.png"
    Image.fromarray(app._image).save(photo)
    app.keeper.photo = PhotoRef.of_file(photo)
    started = time.monotonic()
    with playwright_api.sync_playwright() as playwright:
        browser = launch_chromium(playwright)
        page = browser.new_page(viewport=VIEWPORT, accept_downloads=True)
        page.goto(app.url)
        wait_for(lambda: app.view is not None and app.server.get_clients(), what="first view")
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
        browser.close()
    assert not app.errors, app.errors
    assert time.monotonic() - started < 120
