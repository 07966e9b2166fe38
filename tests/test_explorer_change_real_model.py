"""The change colouring with the shipped model on the shipped photo, without a browser.

Issue 42's target: a box over a forearm makes that forearm's change colouring (its vertices'
uncertainty over the same photo's without the box, default concentrations) >= 1.5x, while the
legs stay within 20 % (the other arm within 35 %: see the test). Driven through the explorer's
state and worker (``ExplorerApp`` with the real predictor, no browser tab), as the Colouring
menu and a shift + drag do.
"""

from __future__ import annotations

import numpy as np
import pytest

from hkpd.explorer.posterior_view import part_uncertainty
from hkpd.kinematic_tree import LIMB_SEGMENT_PARTS

RIGHT_ELBOW, RIGHT_WRIST = 8, 10
"""COCO keypoint indices of the covered forearm's ends."""


@pytest.fixture(scope="module")
def app():
    from hkpd.explorer.app import ExplorerApp
    from hkpd.explorer.demo_photo import shipped_photo
    from hkpd.explorer.provider import PredictorProvider
    from hkpd.prediction.image_input import load_image

    image = np.ascontiguousarray(load_image(shipped_photo()).pixels)
    explorer = ExplorerApp(PredictorProvider(None, device="cpu"), image, port=0,
                           num_displayed=0)  # fmt: skip
    assert explorer.wait_idle(120) and not explorer.errors
    yield explorer
    explorer.stop()


def limb_change(app) -> dict[str, float]:
    """Mean per-vertex change ratio of each limb segment."""
    labels = app.result.posterior.body.part_labels.cpu().numpy()
    parts = part_uncertainty(app.view.change_ratio, labels)
    return {name: float(np.mean([parts[p] for p in ps])) for name, ps in LIMB_SEGMENT_PARTS.items()}


def test_a_covered_forearm_stands_out_in_the_change_colouring(app):
    assert app.result.posterior.source == "evidence"
    app.set_display_options(True, True, True, 10.0, "change")
    assert app.wait_idle(60)
    np.testing.assert_allclose(app.view.change_ratio, 1.0, rtol=1e-5)  # nothing covered yet
    keypoints = app.result.posterior.keypoints.numpy()
    ends = keypoints[[RIGHT_ELBOW, RIGHT_WRIST]]
    low, high = ends.min(axis=0) - 35, ends.max(axis=0) + 35
    assert app.add_occluder((*low, *high))
    assert app.wait_idle(120) and not app.errors
    change = limb_change(app)
    print({name: round(value, 2) for name, value in change.items()})
    assert change["right_forearm"] >= 1.5
    legs = {n: v for n, v in change.items() if n.endswith(("thigh", "lower_leg"))}
    assert all(abs(v - 1.0) <= 0.2 for v in legs.values()), legs
    # The other arm moves a little more: the network reads the boxed crop (its edges painted,
    # two heatmaps dropped) and gives the left arm ~5-10 % less concentration (F norms of the
    # left shoulder and wrist 16.5 -> 15.7 and 17.3 -> 15.4 on this photo). Until issue 58 the
    # box also flipped the mirror choice, which happened to hide it (left arm 1.04-1.05x then,
    # 1.17-1.27x now with the photo's mirror choice kept; docs/explorer.md lesson 1).
    arm = {n: v for n, v in change.items() if n.startswith("left_") and n not in legs}
    assert all(abs(v - 1.0) <= 0.35 for v in arm.values()), arm
    # The colour bar says what is shown.
    assert app.scene.legend_scale.kind == "change"
