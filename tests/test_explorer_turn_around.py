"""The explorer's *Turn around* button (issue 51): the person's turned-around reading
(:meth:`BodyPosterior.turned_around`) shown and turned back, named in the "Not default" line,
kept in scene files (files written before it still load), and in saved pages' captions. Driven
by the test double, whose evidence posteriors are given a turner that turns the distribution
(:func:`hkpd.prediction.turning.turned_distribution`) without a second fit."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from test_explorer_double import OcclusionAwareDouble

from hkpd.explorer.app import ExplorerApp
from hkpd.explorer.panels.turn import AS_READ, TURN, TURN_BACK, TURNED
from hkpd.explorer.provider import PredictionResult
from hkpd.explorer.scene_file import PhotoRef, SceneFile, SceneFileError, parse_scene
from hkpd.prediction.posterior import BodyPosterior
from hkpd.prediction.turning import turned_distribution


def turn(posterior: BodyPosterior) -> BodyPosterior:
    """What the predictor's turner does, without refitting: the depth-mirrored twin."""
    return replace(
        posterior, distribution=turned_distribution(posterior.distribution), turned=True,
        turner=lambda _: posterior,
    )  # fmt: skip


class TurningDouble(OcclusionAwareDouble):
    """The double, with evidence posteriors that can be turned around (as the predictor's)."""

    predictions = 0

    def predict(self, image, occluders, evidence=True, bbox=None) -> PredictionResult:
        self.predictions += 1
        result = super().predict(image, occluders, evidence, bbox)
        turner = turn if evidence else None
        return replace(result, posterior=replace(result.posterior, turner=turner))


def click(button) -> None:
    button.value = True  # what a click does: a button's callbacks always run


@pytest.fixture(scope="module")
def app():
    double = TurningDouble()
    explorer = ExplorerApp(double, double.scene.image, port=0, num_samples=20, num_displayed=2)
    explorer.keeper.photo = PhotoRef("the photo", demo="synthetic")
    assert explorer.wait_idle(60)
    yield explorer
    explorer.stop()


def test_turn_around_and_back(app) -> None:
    section = app.panels.turn
    assert section.button.label == TURN and section.note.content == AS_READ
    as_read = app.view.mode_vertices
    click(section.button)
    assert app.wait_idle(60)
    assert app.result.posterior.turned and app.state.snapshot().turned_around
    assert section.button.label == TURN_BACK and section.note.content == TURNED
    assert "turned around" in app.keeper.differences()
    assert "Turned around: the same keypoints" in app.page_caption().text()
    turned = app.view.mode_vertices
    # The depth-mirrored twin: the mode's vertices mirrored in depth (z -> -z), left and right
    # swapped, so the same points project; the body drawn is another one.
    assert not np.allclose(turned, as_read, atol=1e-3)
    np.testing.assert_allclose(np.sort(turned[:, 2]), np.sort(-as_read[:, 2]), atol=1e-4)
    click(section.button)
    assert app.wait_idle(60)
    assert not app.result.posterior.turned and section.button.label == TURN
    np.testing.assert_allclose(app.view.mode_vertices, as_read, atol=1e-6)
    assert "turned around" not in app.keeper.differences()


def test_occluder_edits_keep_the_turn_and_the_baseline_follows_it(app) -> None:
    app.set_turned_around(True)
    assert app.wait_idle(60)
    app.add_occluder((250, 210, 300, 260))
    assert app.wait_idle(60)
    assert app.result.posterior.turned and app._result_key.turned
    app.clear_occluders()
    app.set_turned_around(False)
    assert app.wait_idle(60) and not app.result.posterior.turned


def test_a_network_only_reading_cannot_be_turned_and_says_so(app) -> None:
    app.set_evidence(False)
    app.set_turned_around(True)
    assert app.wait_idle(60)
    assert not app.result.posterior.turned
    assert app.panels.turn.note.content.startswith("**Not turned around:** this posterior")
    app.set_turned_around(False)
    app.set_evidence(True)
    assert app.wait_idle(60)


def test_scene_files_keep_the_turn_and_old_files_load(app) -> None:
    app.set_turned_around(True)
    assert app.wait_idle(60)
    text = app.keeper.scene().to_json()
    assert json.loads(text)["turned_around"] is True
    app.reset_everything()
    assert app.wait_idle(60) and not app.result.posterior.turned
    app.open_scene(parse_scene(text))
    assert app.wait_idle(60) and app.result.posterior.turned
    assert app.panels.turn.button.label == TURN_BACK
    old = json.loads(text)
    del old["turned_around"]  # a file written before the button existed
    assert parse_scene(json.dumps(old)).turned_around is False
    with pytest.raises(SceneFileError, match="turned_around must be true or false"):
        parse_scene(json.dumps({**old, "turned_around": "yes"}))
    app.reset_everything()
    assert app.wait_idle(60) and not app.result.posterior.turned


def test_a_new_photo_starts_as_read(app) -> None:
    app.set_turned_around(True)
    assert app.wait_idle(60)
    image = app._image
    app.load_upload("again.png", _png(image), None)
    assert app.wait_idle(60)
    assert not app.state.snapshot().turned_around and not app.result.posterior.turned
    assert app.panels.turn.button.label == TURN
    assert SceneFile(photo=PhotoRef("x", demo="synthetic")).turned_around is False


def _png(image: np.ndarray) -> bytes:
    import io

    from PIL import Image

    buffer = io.BytesIO()
    Image.fromarray(image).save(buffer, format="PNG")
    return buffer.getvalue()


def test_the_command_line_saves_a_turned_scene_and_refuses_it_without_evidence(tmp_path) -> None:
    from hkpd.explorer import cli

    path = tmp_path / "turned.json"
    common = ["--demo", "synthetic", "--provider", "test_explorer_double:OcclusionAwareDouble"]
    assert cli.main([*common, "--turn-around", "--save-scene", str(path)]) == 0
    assert json.loads(path.read_text())["turned_around"] is True
    with pytest.raises(SystemExit, match="--turn-around refits the keypoints"):
        cli.main([*common, "--turn-around", "--no-evidence", "--save-scene", str(path)])


def test_the_button_turns_the_shown_reading_without_predicting_it_again(app) -> None:
    double = app.provider
    app.set_turned_around(False)
    app.add_occluder((250, 210, 300, 260))
    assert app.wait_idle(60)
    shown, before = app.result.posterior, double.predictions
    app.set_turned_around(True)
    assert app.wait_idle(60)
    assert double.predictions == before and app.result.posterior.turned
    app.set_turned_around(False)
    assert app.wait_idle(60)
    assert double.predictions == before and app.result.posterior is shown
    # An edit and the button together: the edit is predicted, then turned.
    app.clear_occluders()
    app.set_turned_around(True)
    assert app.wait_idle(60)
    assert double.predictions > before and app.result.posterior.turned
    assert app.state.snapshot().active_boxes == [] and app._result_key.turned
    app.set_turned_around(False)
    assert app.wait_idle(60)
