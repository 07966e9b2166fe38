"""The lean to read a view at when its keypoints show no torso.

:func:`hkpd.prediction.readings.upright_view.torso_tilt` reads a person's lean off the observed
shoulder, hip, knee and head keypoints. When neither end of the torso (nor a stand-in) is
observed, e.g. a view showing only the legs and arms, or a torso covered by an occluder, it has
no answer. Read as they are, such views of the any-orientation synthetic test split (5 %) were
42 px from the truth against 9 px for the rest; turned by the lean of the network's own reading,
read again twice, 28.5 px. The network reads leaning bodies badly, so its own lean is a poor
guide; but a reading of a copy turned near upright fits the keypoints that *are* shown far
better than the others. So such a view is read as it is, at every lean of
:data:`LEAN_CANDIDATES_DEGREES` and at the lean of its own reading (:func:`mode_torso_tilts`),
each reading is mapped back to the crop, and the one whose most likely body projects closest to
the shown keypoints wins (:func:`mode_keypoint_misfits`): 16.0 px on those views with the
shipped network, as good as turning by the true lean (16.1 px;
``docs/experiments/torsoless_lean_search.py``).
"""

from __future__ import annotations

import numpy as np
import torch

from hkpd.body import BodyModel
from hkpd.body.root_relative import pelvis_relative_body
from hkpd.camera_conventions import ndc_to_pixels, weak_perspective_project
from hkpd.distributions import BodyDistribution
from hkpd.prediction.readings.upright_view import torso_tilt

LEAN_CANDIDATES_DEGREES = tuple(range(30, 360, 30))
"""Leans (degrees, clockwise on screen) a torso-less view is also read at, besides as it is."""

TURNED_FIT_MARGIN = 0.1
"""A turned reading replaces the reading as it is only when its body fits the shown keypoints
this share closer (a network that reads the view equally well either way keeps it as it is)."""

_ALL_KEYPOINTS = np.ones(17, dtype=bool)


@torch.no_grad()
def mode_torso_tilts(
    output: BodyDistribution, body: BodyModel, crop_size: int
) -> list[float | None]:
    """The lean of each example's most likely body, as the keypoints would show it.

    Args:
        output: the network's output for ``B`` examples, in their crops' frames.
        body: the body model (keypoint regressor required), on the output's device.
        crop_size: side of the crops in pixels.

    Returns:
        ``B`` angles in radians (clockwise on screen, as
        :func:`hkpd.prediction.readings.upright_view.torso_tilt`), None where the body's torso
        projects to a point (seen exactly end-on).
    """
    keypoints, _ = pelvis_relative_body(
        body, output.shape_mean, output.pose_distribution().mode, output.global_orient
    )
    pixels = ndc_to_pixels(weak_perspective_project(keypoints, output.camera), crop_size)
    points = pixels.detach().double().cpu().numpy()
    return [torso_tilt(example, _ALL_KEYPOINTS) for example in points]


@torch.no_grad()
def mode_keypoint_misfits(
    output: BodyDistribution,
    body: BodyModel,
    crop_size: int,
    keypoints: np.ndarray,
    observed: np.ndarray,
) -> np.ndarray:
    """How far each example's most likely body projects from the keypoints shown.

    Args:
        output: the network's output for ``B`` examples, in their crops' frames.
        body: the body model (keypoint regressor required), on the output's device.
        crop_size: side of the crops in pixels.
        keypoints: ``(B, 17, 2)`` shown keypoints, crop pixels.
        observed: ``(B, 17)`` bool, which of them are shown.

    Returns:
        ``(B,)`` float64: mean distance in crop pixels over the shown keypoints (0 where none is).
    """
    joints, _ = pelvis_relative_body(
        body, output.shape_mean, output.pose_distribution().mode, output.global_orient
    )
    pixels = ndc_to_pixels(weak_perspective_project(joints, output.camera), crop_size)
    projected = pixels.detach().double().cpu().numpy()
    distances = np.linalg.norm(projected - np.asarray(keypoints, dtype=np.float64), axis=-1)
    shown = np.asarray(observed, dtype=bool)
    counts = shown.sum(-1)
    return np.where(counts > 0, (distances * shown).sum(-1) / np.maximum(counts, 1), 0.0)
