"""Compare: a second set of columns (B) for one alternative setting of the same photo and
person, the change colouring between the two (B ÷ A), in the app, its panel, its pages and
scene files. Driven by the test double (which lowers a joint's concentration 30-fold when the
keypoint revealing it is covered), so B's numbers are known in advance."""

from __future__ import annotations

import numpy as np
import pytest
from test_explorer_double import COCO, OcclusionAwareDouble

from hkpd.explorer.app import ExplorerApp, framing
from hkpd.explorer.compare import CompareSetting, parse_compare
from hkpd.explorer.compare_scene import COMPARE_HEAT_OFFSET
from hkpd.explorer.panels.compare import MODEL, choice_of
from hkpd.explorer.posterior_view import part_uncertainty
from hkpd.explorer.provider import PredictionResult


class SureDouble(OcclusionAwareDouble):
    """ "Another model": the double, twice as concentrated everywhere."""

    def predict(self, image, occluders, evidence=True, bbox=None) -> PredictionResult:
        result = super().predict(image, occluders, evidence, bbox)
        return PredictionResult(result.posterior.with_concentration(list(range(23)), 2.0))


def forearm(view, double, side: str = "left") -> float:
    parts = part_uncertainty(view.uncertainty, double.body.part_labels.numpy())
    return parts[f"{side}_elbow"]


@pytest.fixture(scope="module")
def app():
    double = OcclusionAwareDouble()
    explorer = ExplorerApp(double, double.scene.image, port=0, num_samples=30, num_displayed=2)
    explorer.double = double
    explorer.compare._load_model = lambda path: SureDouble(double.scene, double.body)
    wrist = double.scene.keypoints2d[COCO.index("left_wrist")]
    explorer.add_occluder((wrist[0] - 12, wrist[1] - 12, wrist[0] + 12, wrist[1] + 12))
    assert explorer.wait_idle(60)
    yield explorer
    explorer.stop()


def test_parse_compare_settings(tmp_path) -> None:
    assert parse_compare("network") == CompareSetting("network")
    checkpoint = tmp_path / "other.pt"
    checkpoint.write_bytes(b"x")
    setting = parse_compare(str(checkpoint))
    assert setting.kind == "model" and setting.label == "model other.pt"
    assert setting.text == str(checkpoint)
    with pytest.raises(ValueError, match="use one of network, no-occluders"):
        parse_compare("networks")
    assert choice_of(setting) == MODEL and choice_of(None) == "Off"


def test_no_occluders_b_is_surer_where_the_box_hides_evidence(app) -> None:
    app.panels.compare.menu.value = "B: without the boxes"  # what a click in the menu does
    assert app.wait_idle(60)
    view_a, view_b = app.view, app.compare.view
    assert view_b is not None and app.compare_columns.shown
    assert forearm(view_b, app.double) < 0.85 * forearm(view_a, app.double)
    right_a, right_b = forearm(view_a, app.double, "right"), forearm(view_b, app.double, "right")
    assert right_b == pytest.approx(right_a, rel=1e-6)  # same seed: the same draw there
    assert np.allclose(
        view_b.change_ratio, view_b.uncertainty / np.maximum(view_a.uncertainty, 1e-4)
    )
    assert "| left forearm |" in app.panels.compare.numbers.content
    caption = app.page_caption().text()
    assert "Further right, B (without the boxes)" in caption and "B ÷ A" in caption
    assert "/compare_heat/points" in app.server.scene._handle_from_node_name
    # The framing makes room for B's columns.
    (x, _, distance), _ = framing(app.scene.placement, 1.6, 1.0, compare=True)
    (x0, _, distance0), _ = framing(app.scene.placement, 1.6, 1.0)
    assert distance > distance0 and x > x0 and COMPARE_HEAT_OFFSET > 3


def test_default_concentrations_and_another_model(app) -> None:
    app.panels.concentration.joints["left_elbow"].track.value = (-1.0,)
    app.panels.compare.menu.value = "B: concentrations at 1×"
    assert app.wait_idle(60)
    assert forearm(app.compare.view, app.double) < forearm(app.view, app.double)
    drawn = app.compare.view
    app.panels.concentration.joints["left_elbow"].track.value = (-0.5,)  # A moves, B does not
    assert app.wait_idle(60) and app.compare.reused
    assert app.compare.view.sample_vertices is drawn.sample_vertices
    assert not np.array_equal(app.compare.view.change_ratio, drawn.change_ratio)
    app.panels.concentration.joints["left_elbow"].track.value = (0.0,)
    app.panels.compare.menu.value = MODEL
    app.panels.compare.checkpoint.value = __file__  # any existing file: the loader is stubbed
    assert app.wait_idle(60)
    ratio = app.compare.view.change_ratio
    assert app.compare.setting.kind == "model" and 0.5 < float(np.median(ratio)) < 0.85
    assert app.keeper.settings().compare == __file__
    app.panels.compare.checkpoint.value = "/no/such/checkpoint.pt"
    assert "does not exist" in app.panels.compare.numbers.content
    app.set_compare(None)
    assert app.wait_idle(60)
    assert app.compare.view is None and not app.compare_columns.shown
    assert "/compare_heat/points" not in app.server.scene._handle_from_node_name
    assert app.panels.compare.menu.value == "Off"


def test_change_colouring_titles_follow_it(app) -> None:
    app.set_compare(CompareSetting("no-occluders"))
    app.panels.samples.colouring.value = "Change vs. no occluders, default concentrations (×)"
    assert app.wait_idle(60)
    labels = {
        name: handle.text
        for name, handle in app.server.scene._handle_from_node_name.items()
        if name.startswith("/titles/")
    }
    # Beside B, A's titles say "A" (issue 58), all in short lines: none wider than the
    # columns stand apart ("samplesUncertainty" ran together).
    assert labels["/titles/uncertainty"].startswith("A: change: uncertainty\n÷ no occluders")
    assert labels["/titles/samples"] == "A: most likely body\n+ samples"
    assert labels["/titles/compare_title_heat"] == "B (without the boxes):\nuncertainty ÷ A's"
    body_b = labels["/titles/compare_title_body"]
    assert body_b == "B (without the boxes):\nmost likely body\n+ samples"
    assert max(len(line) for text in labels.values() for line in text.split("\n")) <= 22
    assert "coloured by B's spread ÷ A's" in app.page_caption().text()
    app.panels.samples.colouring.value = "Uncertainty, log scale (cm)"
    app.set_compare(None)
    assert app.wait_idle(60)
    titles = app.server.scene._handle_from_node_name
    assert titles["/titles/uncertainty"].text == "Uncertainty\nover samples"
    assert titles["/titles/samples"].text == "Most likely body\n+ samples"  # no B: no "A"


def test_a_slider_move_redraws_only_what_b_changed(app) -> None:
    """A slider B follows re-samples B, but B's most likely body is computed once per
    prediction (sliders never move a mode) and its titles and colour bar are not sent again;
    what B shows is what a fresh view of B shows."""
    from hkpd.explorer.posterior_view import compute_view

    app.set_compare(CompareSetting("network"))
    assert app.wait_idle(60)
    prediction = app.compare._prediction
    titles = app.compare_columns._nodes["title_heat"]
    points = app.compare_columns._nodes["points"]
    app.sampling_changed(app.state.set_joint_exponent("left_elbow", -0.7))
    assert app.wait_idle(60)
    view_b, snapshot = app.compare.view, app.state.snapshot()
    assert app.compare._prediction is prediction and len(prediction.mode) == 1
    fresh = compute_view(prediction.posterior, snapshot, app.view.uncertainty)
    np.testing.assert_allclose(view_b.mode_vertices, fresh.mode_vertices, atol=1e-6)
    np.testing.assert_array_equal(view_b.uncertainty, fresh.uncertainty)
    np.testing.assert_array_equal(view_b.sample_vertices, fresh.sample_vertices)
    nodes = app.compare_columns._nodes
    assert nodes["title_heat"] is titles and nodes["points"] is points  # kept, not re-added
    app.panels.samples.colouring.value = "Change vs. no occluders, default concentrations (×)"
    assert app.wait_idle(60)
    assert app.compare_columns._nodes["title_heat"].text == "B (network only):\nuncertainty ÷ A's"
    app.panels.samples.colouring.value = "Uncertainty, log scale (cm)"
    app.sampling_changed(app.state.set_joint_exponent("left_elbow", 0.0))
    app.set_compare(None)
    assert app.wait_idle(60) and not app.compare_columns.shown


def test_network_b_is_the_reading_a_s_fit_updated_when_there_is_one() -> None:
    """Compare's ``network`` B takes A's ``prior`` (the network's reading its fit updated: what
    predicting with the evidence off returns) instead of predicting again; without one (the
    network alone, a turned reading, the double's posteriors) it predicts."""
    from dataclasses import replace

    from hkpd.explorer.compare import Comparison, network_reading
    from hkpd.explorer.state import ExplorerState

    double = OcclusionAwareDouble()
    image = double.scene.image
    network = double.predict(image, [], evidence=False).posterior
    conditioned = replace(network, source="evidence", prior=network)
    assert network_reading(conditioned) is network
    assert network_reading(network) is None
    assert network_reading(replace(conditioned, turned=True)) is None
    calls = []

    def predict(*arguments) -> PredictionResult:
        calls.append(arguments)
        return double.predict(image, [], evidence=False)

    comparison = Comparison(predict)
    comparison.set_setting(CompareSetting("network"))
    state = ExplorerState()
    state.set_image(image.shape[1], image.shape[0])
    comparison.predict(image, state.snapshot(), PredictionResult(conditioned))
    assert comparison._prediction.posterior is network and not calls
    comparison.predict(image, state.snapshot(), PredictionResult(network))  # nothing kept
    assert len(calls) == 1 and calls[0][2] is False  # predicted with the evidence off
