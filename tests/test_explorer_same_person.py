"""The explorer's "Add a photo of the same person": the shapes of further photos of the current
person are kept and combined with the current photo's into one shape, drawn in a T-pose coloured
by shape uncertainty. Driven like ``test_explorer_app.py``: in-process server, test double."""

from __future__ import annotations

import io
from dataclasses import replace

import numpy as np
import pytest
import torch
from PIL import Image
from test_explorer_app import RecordingClient
from test_explorer_double import OcclusionAwareDouble

from hkpd.explorer.app import ExplorerApp, framing
from hkpd.explorer.photo_geometry import PhotoPlacement
from hkpd.explorer.state import MAX_SAME_PERSON_PHOTOS, ExplorerState
from hkpd.prediction.detection.keypoint_detector import NoPersonFoundError
from hkpd.prediction.shape_combination import product_of_gaussians

BASE_STD = 0.08


class ShapeByPhotoDouble(OcclusionAwareDouble):
    """The demo double, but each photo's shape Gaussian depends on its top-left pixel ``k``:
    mean ``betas + 0.1 k``, std ``0.08 (k + 1)``; a flat grey photo has no person."""

    def predict(self, image, occluders, evidence=True, bbox=None):
        if np.asarray(image).std() < 1.0:
            raise NoPersonFoundError("photo: no person found")
        result = super().predict(image, occluders, evidence, bbox)
        k = float(np.asarray(image)[0, 0, 0])
        distribution = replace(
            result.posterior.distribution,
            shape_mean=result.posterior.shape_mean + 0.1 * k,
            shape_std=torch.full_like(result.posterior.shape_std, BASE_STD * (k + 1)),
        )
        posterior = replace(result.posterior, distribution=distribution)
        return replace(result, posterior=posterior)


def photo(image: np.ndarray, k: int) -> np.ndarray:
    marked = image.copy()
    marked[0, 0] = k
    return marked


def png(image: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    Image.fromarray(image).save(buffer, format="PNG")
    return buffer.getvalue()


@pytest.fixture(scope="module")
def app():
    double = ShapeByPhotoDouble()
    explorer = ExplorerApp(double, photo(double.scene.image, 0), port=0, num_displayed=1)
    explorer.double = double
    assert explorer.wait_idle(60)
    yield explorer
    explorer.stop()


def nodes(app) -> set[str]:
    return set(app.server.scene._handle_from_node_name)


def test_before_any_added_photo_there_is_no_combined_shape(app):
    assert app.combined_shape is None
    assert "/combined/points" not in nodes(app)
    assert "Only the current photo" in app.panels.same_person.text.content


def test_an_added_photo_is_combined_with_the_current_one(app):
    client = RecordingClient()
    image = app.double.scene.image
    app.add_same_person_upload("second.png", png(photo(image, 0)), client)
    assert app.wait_idle(60) and not app.errors
    combined = app.combined_shape
    assert combined is not None and combined.count == 2
    betas = app.double.scene.betas.double()
    torch.testing.assert_close(combined.betas_mean.double(), betas, atol=1e-6, rtol=1e-6)
    torch.testing.assert_close(combined.betas_std, torch.full((10,), BASE_STD / 2**0.5).double())
    assert ("Photo added", "second.png: 2 photos of this person") in client.notifications
    assert {"/combined/base", "/combined/points", "/combined_title"} <= nodes(app)
    text = app.panels.same_person.text.content
    assert "**2 photos**" in text and "second.png" in text and "0.057" in text  # 0.08 / sqrt 2
    # A sure photo and an unsure one: the product weights them by precision.
    app.add_same_person_photo(photo(image, 3), "unsure.png", client)
    assert app.wait_idle(60)
    stds = torch.tensor([BASE_STD, BASE_STD, 4 * BASE_STD]).double()[:, None].expand(3, 10)
    means = betas[None] + torch.tensor([0.0, 0.0, 0.3]).double()[:, None]
    expected_mean, expected_std = product_of_gaussians(means, stds)
    combined = app.combined_shape
    assert combined.count == 3
    torch.testing.assert_close(combined.betas_mean.double(), expected_mean, atol=1e-6, rtol=1e-6)
    torch.testing.assert_close(combined.betas_std.double(), expected_std)
    # Shape only changes the T-pose: the drawn body is the combined mean's, pelvis at 0.
    assert combined.tpose_vertices.shape == (13492, 3)
    assert float(combined.vertex_uncertainty.mean()) > 0


def test_the_combination_follows_the_current_photos_prediction(app):
    before = app.combined_shape.betas_mean.clone()
    assert app.add_occluder((10, 10, 60, 60))  # predicts the current photo again
    assert app.wait_idle(60)
    assert app.combined_shape is not None and app.combined_shape.count == 3
    torch.testing.assert_close(app.combined_shape.betas_mean, before)
    app.clear_occluders()
    assert app.wait_idle(60)


def world_box(app, frame: str, mesh: str) -> np.ndarray:
    """``(2, 3)`` world min and max of a body drawn in a turned frame (body y down -> up)."""
    handles = app.server.scene._handle_from_node_name
    vertices = handles[mesh].vertices * np.array([1.0, -1.0, -1.0]) + handles[frame].position
    return np.stack([vertices.min(axis=0), vertices.max(axis=0)])


def test_the_combined_body_is_drawn_at_scale_beside_the_others_without_overlaps(app):
    handles = app.server.scene._handle_from_node_name
    combined = world_box(app, "/combined", "/combined/base")
    heat = world_box(app, "/heat", "/heat/base")
    mode = world_box(app, "/body", "/body/mode")
    tpose = app.combined_shape.tpose_vertices.numpy()
    # Scale 1, like the other bodies: its drawn height is the T-pose's own (metres).
    np.testing.assert_allclose(combined[1] - combined[0], np.ptp(tpose, axis=0), rtol=1e-5)
    assert 1.0 < combined[1, 1] - combined[0, 1] < 2.2  # a person's height, not twice it
    # Side by side, apart: the three bodies' x ranges do not overlap.
    assert mode[1, 0] < heat[0, 0] and heat[1, 0] < combined[0, 0]
    # Its title sits in the row of the column titles, above every body.
    title = handles["/combined_title"]
    assert title.position[1] == pytest.approx(app.scene.titles_top)
    assert title.position[1] > max(combined[1, 1], heat[1, 1], mode[1, 1])
    assert "std" not in title.text  # short, like the other titles (the panel gives the std)
    # Its own colour bar under its feet, beside (not on) the uncertainty body's.
    legend = handles["/combined_legend"]
    assert legend.position[1] < combined[0, 1]
    bar = handles["/legend"]
    assert legend.position[0] - bar.position[0] >= legend.render_width


def test_photos_that_cannot_be_added_say_why_and_change_nothing(app):
    client = RecordingClient()
    count = app.combined_shape.count
    app.add_same_person_upload("notes.txt", b"hello", client)
    app.add_same_person_photo(np.full((120, 90, 3), 128, np.uint8), "grey.png", client)
    assert app.wait_idle(60)
    titles = [title for title, _ in client.notifications]
    assert titles == ["Photo not added", "Photo not added"]
    assert "grey.png: no person found" in client.notifications[1][1]
    assert app.combined_shape.count == count


def test_forgetting_the_added_photos_removes_the_combined_shape(app):
    app.clear_same_person()
    assert app.wait_idle(60)
    assert app.combined_shape is None and app.state.snapshot().same_person == ()
    assert "/combined/points" not in nodes(app) and "/combined_title" not in nodes(app)
    assert "Only the current photo" in app.panels.same_person.text.content


def test_a_new_photo_starts_a_new_person(app):
    client = RecordingClient()
    image = app.double.scene.image
    app.add_same_person_photo(photo(image, 1), "again.png", client)
    assert app.wait_idle(60) and app.combined_shape.count == 2
    app._image_job(photo(image, 2), "someone_else.png", client)
    assert app.wait_idle(60)
    assert app.state.snapshot().same_person == () and app.combined_shape is None
    assert "/combined/points" not in nodes(app)


def test_the_framing_makes_room_for_the_combined_body():
    placement = PhotoPlacement(400, 600, (-1.5, 0.0, 0.0), 2.0)
    (x, _, distance), _ = framing(placement, 1.6)
    (x_wide, _, distance_wide), _ = framing(placement, 1.6, combined=True)
    assert x_wide > x and distance_wide > distance


def test_state_keeps_at_most_the_limit_and_checks_the_numbers():
    state = ExplorerState()
    for index in range(MAX_SAME_PERSON_PHOTOS):
        assert state.add_same_person_shape(f"{index}.jpg", (0.0,) * 10, (1.0,) * 10)
    assert not state.add_same_person_shape("one_too_many.jpg", (0.0,) * 10, (1.0,) * 10)
    assert len(state.snapshot().same_person) == MAX_SAME_PERSON_PHOTOS
    other = ExplorerState()
    other.add_same_person_shape("a", (0.0,) * 10, (1.0,) * 10)
    with pytest.raises(ValueError, match="this photo has 8 shape coefficients, the kept ones"):
        other.add_same_person_shape("b", (0.0,) * 8, (1.0,) * 8)
    with pytest.raises(ValueError, match="finite and > 0"):
        ExplorerState().add_same_person_shape("a", (0.0,) * 10, (0.0,) * 10)
    with pytest.raises(ValueError, match="same length"):
        ExplorerState().add_same_person_shape("a", (0.0,) * 10, (1.0,) * 9)
    assert state.clear_same_person() and not state.clear_same_person()
    state.add_same_person_shape("x.jpg", (0.0,) * 10, (1.0,) * 10)
    state.set_image(100, 100)  # a new photo: a new person
    assert state.snapshot().same_person == ()
