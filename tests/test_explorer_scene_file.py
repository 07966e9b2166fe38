"""Scene files: save a scene (photo by path + checksum or embedded, boxes, concentrations,
switches, display settings, seed, model, compare), reopen it (command line, panel) and get the
same page and bit-identical posteriors; clear errors for every way a file can be wrong; undo,
redo and "Reset everything" in the app. Driven by the test double of the predictor."""

from __future__ import annotations

import html
import json
import re

import numpy as np
import pytest
import torch
from PIL import Image
from test_explorer_double import OcclusionAwareDouble

from hkpd.explorer import cli, cli_scene, scene_keeping
from hkpd.explorer.app import ExplorerApp
from hkpd.explorer.html_page import CAPTION_ID
from hkpd.explorer.scene_file import (
    DisplaySettings,
    OccluderEntry,
    PhotoRef,
    SceneFile,
    SceneFileError,
    load_scene,
    parse_scene,
)
from hkpd.explorer.scene_keeping import describe_differences

DOUBLE = "test_explorer_double:OcclusionAwareDouble"
SETTINGS = ["--samples", "20", "--meshes", "2", "--occluder", "250", "210", "300", "260",
            "--concentration", "left_elbow", "0.1", "--seed", "3",
            "--colouring", "change"]  # fmt: skip


def caption_of(page: str) -> str:
    found = re.search(f'<div id="{CAPTION_ID}"[^>]*>(.*?)</div>', page, re.S)
    assert found is not None
    return html.unescape(found.group(1))


def test_a_scene_round_trips_through_json_and_refuses_bad_files(tmp_path) -> None:
    photo = tmp_path / "photo.jpg"
    photo.write_bytes(b"not really a jpeg, but bytes with a checksum")
    scene = SceneFile(
        photo=PhotoRef.of_file(photo), person_box=(1.0, 2.0, 30.0, 40.0),
        occluders=(OccluderEntry((5.0, 5.0, 9.0, 9.0), enabled=False),),
        joint_factors={"left_elbow": 0.1}, evidence=False,
        display=DisplaySettings(colouring="linear", num_samples=50), seed=4,
        compare="network",
    )  # fmt: skip
    path = scene.save(tmp_path / "scene.json")
    assert load_scene(path) == scene
    assert load_scene(path).photo.read() == photo.read_bytes()
    with pytest.raises(SceneFileError, match="exists: choose another name"):
        scene.save(path)
    embedded = SceneFile(photo=PhotoRef.of_file(photo, embed=True))
    assert parse_scene(embedded.to_json()).photo.read() == photo.read_bytes()
    assert "left elbow 0.1×" in describe_differences(scene)
    assert describe_differences(SceneFile(photo=scene.photo)) == []

    photo.write_bytes(b"another photo now")
    with pytest.raises(SceneFileError, match="does not match the scene's checksum"):
        load_scene(path).photo.read()
    photo.unlink()
    with pytest.raises(SceneFileError, match="is missing: put it back there"):
        load_scene(path).photo.read()
    data = json.loads(path.read_text())
    for broken, message in (
        ("{not json", "is not valid JSON"),
        (json.dumps({**data, "version": 7}), "of version 7; this hkpd reads version 1"),
        (json.dumps({"some": "thing"}), "is not an hkpd explorer scene"),
        (json.dumps({**data, "joint_factors": {"left_elbw": 2}}), "unknown joint 'left_elbw'"),
        (json.dumps({**data, "joint_factors": {"left_elbow": 50}}), "must be in 0.1..10"),
        ("<html><body>no scene</body></html>", "without an hkpd scene"),
    ):
        with pytest.raises(SceneFileError, match=message):
            parse_scene(broken, "scene.json")
    with pytest.raises(SceneFileError, match="does not exist"):
        load_scene(tmp_path / "missing.json")


def test_a_page_from_a_saved_scene_equals_the_page_from_the_command_line(
    tmp_path, monkeypatch, capsys
) -> None:
    monkeypatch.chdir(tmp_path)
    base = ["--demo", "synthetic", "--provider", DOUBLE, *SETTINGS]
    assert cli.main([*base, "--save-scene", "scene.json"]) == 0  # writes, serves nothing
    assert "wrote scene.json" in capsys.readouterr().out
    with pytest.raises(SystemExit, match="exists: choose another name, or pass --force"):
        cli.main([*base, "--save-scene", "scene.json"])
    assert cli.main([*base, "--export-html", "direct.html"]) == 0
    assert (
        cli.main(["--scene", "scene.json", "--provider", DOUBLE, "--export-html", "saved.html"])
        == 0
    )
    direct = (tmp_path / "direct.html").read_text()
    saved = (tmp_path / "saved.html").read_text()
    assert caption_of(saved) == caption_of(direct) + " Scene: scene.json."
    assert "Mean vertex uncertainty: whole body" in caption_of(direct)
    assert "left elbow 0.1×" in caption_of(direct) and "Network only." in caption_of(direct)
    # The page records its scene, and reopens as one.
    assert parse_scene(saved) == load_scene(tmp_path / "scene.json")
    assert (
        cli.main(["--scene", "saved.html", "--provider", DOUBLE, "--export-html", "again.html"])
        == 0
    )
    assert caption_of((tmp_path / "again.html").read_text()).startswith(caption_of(direct))
    with pytest.raises(SystemExit, match="either a photo and its options or --scene"):
        cli.main(["--scene", "scene.json", "--occluder", "1", "1", "9", "9"])


@pytest.fixture(scope="module")
def double():
    return OcclusionAwareDouble()


def test_a_reopened_scene_gives_bit_identical_posteriors(double, tmp_path) -> None:
    first = ExplorerApp(double, double.scene.image, port=0, num_samples=20, num_displayed=2)
    try:
        assert first.wait_idle(60)
        photo = tmp_path / "demo.png"
        Image.fromarray(double.scene.image).save(photo)
        first.keeper.photo = PhotoRef.of_file(photo)
        first.add_occluder((250, 210, 300, 260))
        first.panels.concentration.joints["left_elbow"].track.value = (-0.5,)
        first.panels.samples.seed.value = 5
        assert first.wait_idle(60)
        assert "left elbow 0.32×" in first.panels.keep.changes.content
        assert "1 occluder(s)" in first.panels.keep.changes.content
        saved = first.keeper.scene().save(tmp_path / "scene.json")
        view_a, posterior_a = first.view, first.result.posterior
    finally:
        first.stop()
    second = ExplorerApp(double, double.scene.image, port=0)
    try:
        assert second.wait_idle(60)
        second.open_scene(load_scene(saved), source="scene.json")
        assert second.wait_idle(60)
        assert torch.equal(second.result.posterior.F, posterior_a.F)
        assert np.array_equal(second.view.uncertainty, view_a.uncertainty)
        assert np.array_equal(second.view.sample_vertices, view_a.sample_vertices)
        elbow = second.panels.concentration.joints["left_elbow"]
        assert elbow.box.value == pytest.approx(0.316, abs=1e-3)
        assert second.keeper.source == "scene.json"
    finally:
        second.stop()


def test_undo_redo_and_reset_everything(double, monkeypatch) -> None:
    monkeypatch.setattr(scene_keeping, "EDIT_PAUSE_S", 0.0)  # every view is its own edit
    app = ExplorerApp(double, double.scene.image, port=0, num_samples=20, num_displayed=2)
    try:
        assert app.wait_idle(60)
        app.add_occluder((250, 210, 300, 260))
        assert app.wait_idle(60)
        app.panels.concentration.joints["left_knee"].box.value = 10.0
        assert app.wait_idle(60)
        assert app.undo() and app.wait_idle(60)
        assert app.state.snapshot().joint_exponents == (0.0,) * 23
        assert len(app.state.snapshot().occluders) == 1
        assert app.undo() and app.wait_idle(60)
        assert app.state.snapshot().occluders == ()
        assert not app.undo()  # nothing before the first view
        assert app.redo() and app.redo() and app.wait_idle(60)
        assert len(app.state.snapshot().occluders) == 1
        assert max(app.state.snapshot().joint_exponents) == 1.0
        app.panels.samples.colouring.value = "Change vs. no occluders, default concentrations (×)"
        app.reset_everything()
        assert app.wait_idle(60)
        snapshot = app.state.snapshot()
        assert snapshot.occluders == () and max(snapshot.joint_exponents) == 0.0
        assert app.scene.heatmap.kind == "log"
        assert app.panels.keep.changes.content == "*Everything at its defaults.*"
        # A slider dragged through many values without a pause is one edit.
        monkeypatch.setattr(scene_keeping, "EDIT_PAUSE_S", 60.0)
        for exponent in (-0.2, -0.4, -0.6, -0.8):
            app.panels.concentration.joints["left_knee"].track.value = (exponent,)
            assert app.wait_idle(60)
        assert app.undo() and app.wait_idle(60)
        assert app.state.snapshot().joint_exponents == (0.0,) * 23
    finally:
        app.stop()


def test_a_scene_keeps_the_stated_body(tmp_path) -> None:
    from hkpd.explorer.scene_keeping import DEFAULT_PHOTO as photo_ref

    scene = SceneFile(photo=photo_ref, sex="male", measurements={"height_m": [1.85, 0.01]})
    again = parse_scene(scene.to_json())
    assert again.sex == "male" and again.measurements == {"height_m": [1.85, 0.01]}
    assert again.stated().measurements == {"height_m": (1.85, 0.01)}
    with pytest.raises(SceneFileError, match="stated body"):
        SceneFile(photo=photo_ref, measurements={"height_m": [185.0, 1.0]})
    with pytest.raises(SceneFileError, match="stated body"):
        SceneFile(photo=photo_ref, sex="man")


def test_the_stated_body_is_a_difference_from_the_defaults() -> None:
    from hkpd.explorer.scene_keeping import DEFAULT_PHOTO as photo_ref

    scene = SceneFile(photo=photo_ref, sex="female", measurements={"mass_kg": [60.0, 1.0]})
    assert any(item.startswith("stated: female") for item in describe_differences(scene))


def test_a_scene_of_the_shipped_photo_reopens_on_any_install(tmp_path, monkeypatch) -> None:
    """The shipped photo is named as the shipped photo (marker + checksum), not by this
    machine's path: its scene, its embedded scene, its page and an older scene holding another
    machine's absolute path all open with ``--scene``."""
    monkeypatch.chdir(tmp_path)
    assert cli.main(["--occluder", "377", "255", "473", "290", "--save-scene", "s.json"]) == 0
    photo = json.loads((tmp_path / "s.json").read_text())["photo"]
    assert photo["demo"] == "shipped" and "path" not in photo
    assert cli.main(["--embed-photo", "--save-scene", "e.json"]) == 0
    assert cli.main(["--provider", DOUBLE, "--samples", "4", "--meshes", "1",
                     "--export-html", "page.html"]) == 0  # fmt: skip
    older = json.loads((tmp_path / "s.json").read_text())
    elsewhere = "/home/teacher/venv/hkpd/assets/photos/warrior_lunge.jpg"
    older["photo"] = {"name": "the shipped CC0 photo", "sha256": photo["sha256"], "path": elsewhere}
    (tmp_path / "older.json").write_text(json.dumps(older))
    for name in ("s.json", "e.json", "page.html", "older.json"):
        image = cli_scene.open_scene_file(name)[1]
        assert image is not None and image.shape == (720, 1080, 3), name
    assert cli_scene.open_scene_file("s.json")[0].active_boxes == [(377.0, 255.0, 473.0, 290.0)]
    older["photo"]["sha256"] = "0" * 64  # another photo, missing here: still refused
    (tmp_path / "other.json").write_text(json.dumps(older))
    with pytest.raises(SystemExit, match="is missing: put it back there"):
        cli_scene.open_scene_file("other.json")
