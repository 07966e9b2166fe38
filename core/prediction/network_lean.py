"""The lean of the body a network read: the upright reading's stand-in when the keypoints show no
torso.

:func:`hkpd.prediction.upright_view.torso_tilt` reads a person's lean off the observed shoulder,
hip, knee and head keypoints. When neither end of the torso (nor a stand-in) is observed, e.g. a
view showing only the legs and arms, or a torso covered by an occluder, it has no answer, and such
a view was read as it is, whatever its orientation: on the any-orientation synthetic test split
those views (5 %) were 42 px from the truth against 9 px for the rest. The network's own reading
of the view still poses a whole body, so its mode's projected keypoints give a lean:
:func:`mode_torso_tilts`. Reading the copy turned by that lean and taking the lean of *that*
reading again converges on the person's orientation: on those views of the split, with the shipped
network, one reading turned by the network's lean gives 33 px, a second 28.5 px, a third 27 px
(turned by the true lean: 16 px). :data:`LEAN_REREADINGS` is the number of turned readings used.
"""

from __future__ import annotations

import numpy as np
import torch

from hkpd.body import BodyModel
from hkpd.body.root_relative import pelvis_relative_body
from hkpd.camera_conventions import ndc_to_pixels, weak_perspective_project
from hkpd.network.output import NetworkOutput
from hkpd.prediction.upright_view import torso_tilt

LEAN_REREADINGS = 2
"""Turned readings after the first, each turned by the lean of the previous reading's mode."""

_ALL_KEYPOINTS = np.ones(17, dtype=bool)


@torch.no_grad()
def mode_torso_tilts(output: NetworkOutput, body: BodyModel, crop_size: int) -> list[float | None]:
    """The lean of each example's most likely body, as the keypoints would show it.

    Args:
        output: the network's output for ``B`` examples, in their crops' frames.
        body: the body model (keypoint regressor required), on the output's device.
        crop_size: side of the crops in pixels.

    Returns:
        ``B`` angles in radians (clockwise on screen, as
        :func:`hkpd.prediction.upright_view.torso_tilt`), None where the body's torso projects
        to a point (seen exactly end-on).
    """
    keypoints, _ = pelvis_relative_body(
        body, output.shape_mean, output.pose_distribution().mode, output.global_orient
    )
    pixels = ndc_to_pixels(weak_perspective_project(keypoints, output.camera), crop_size)
    points = pixels.detach().double().cpu().numpy()
    return [torso_tilt(example, _ALL_KEYPOINTS) for example in points]
