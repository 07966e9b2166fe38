"""A TEST DOUBLE for the predictor, used by the explorer's tests and benchmark (not shipped).

:class:`OcclusionAwareDouble` is honest about what it is: it does not look at pixels to find the
pose. It knows the demo scene's ground truth and builds a :class:`BodyPosterior` by hand: the
mode is the true pose, and a joint's concentration drops 30-fold when the keypoints that
reveal its rotation (the keypoint at the end of the bone it turns) lie under an enabled
occluder, as a trained network would do with the evidence gone. The proxy representation is
computed for real from the occluded photo. The tests in this file check that contract.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from hkpd.body import BodyModel
from hkpd.camera_conventions import pixels_to_ndc
from hkpd.distributions import BodyDistribution
from hkpd.explorer.demo_scene import DemoScene, render_demo_scene
from hkpd.explorer.provider import PredictionResult
from hkpd.kinematic_tree import BODY_JOINT_NAMES
from hkpd.prediction import CropTransform, apply_occluders
from hkpd.prediction.posterior import BodyPosterior
from hkpd.proxy.representation import build_proxy

COCO = ("nose", "left_eye", "right_eye", "left_ear", "right_ear", "left_shoulder",
        "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_hip",
        "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle")  # fmt: skip

EVIDENCE: dict[str, tuple[str, ...]] = {
    "left_hip": ("left_knee",), "right_hip": ("right_knee",),
    "left_knee": ("left_ankle",), "right_knee": ("right_ankle",),
    "left_ankle": ("left_ankle",), "right_ankle": ("right_ankle",),
    "left_foot": ("left_ankle",), "right_foot": ("right_ankle",),
    "spine1": ("left_shoulder", "right_shoulder"), "spine2": ("left_shoulder", "right_shoulder"),
    "spine3": ("left_shoulder", "right_shoulder"),
    "neck": ("nose", "left_ear", "right_ear"), "head": ("nose", "left_eye", "right_eye"),
    "left_collar": ("left_shoulder",), "right_collar": ("right_shoulder",),
    "left_shoulder": ("left_elbow",), "right_shoulder": ("right_elbow",),
    "left_elbow": ("left_wrist",), "right_elbow": ("right_wrist",),
    "left_wrist": ("left_wrist",), "right_wrist": ("right_wrist",),
    "left_hand": ("left_wrist",), "right_hand": ("right_wrist",),
}  # fmt: skip
"""Keypoints whose position reveals each body joint's rotation."""

VISIBLE_CONCENTRATION = 300.0
OCCLUDED_FACTOR = 1.0 / 30.0
AXIS_PROFILE = (1.0, 0.6, 0.35)
"""Singular values of F relative to the largest: the three axes differ, as in real predictions."""


def covered_keypoints(keypoints: np.ndarray, boxes: Sequence[Sequence[float]]) -> np.ndarray:
    """``(17,)`` bool: keypoint pixel centres ``(u, v)`` inside any box (pixel-edge coords)."""
    inside = np.zeros(len(keypoints), dtype=bool)
    for x0, y0, x1, y1 in boxes:
        u, v = keypoints[:, 0] + 0.5, keypoints[:, 1] + 0.5
        inside |= (u >= x0) & (u < x1) & (v >= y0) & (v < y1)
    return inside


class OcclusionAwareDouble:
    """Stands in for the Predictor on the demo photo (see the module docstring)."""

    def __init__(self, scene: DemoScene | None = None, body: BodyModel | None = None) -> None:
        self.scene = render_demo_scene() if scene is None else scene
        self.body = BodyModel() if body is None else body
        height, width = self.scene.image.shape[:2]
        self.crop = CropTransform.from_keypoints(self.scene.keypoints2d, image_size=(width, height))
        self.camera = self._fit_camera()
        self.calls = 0

    def _fit_camera(self) -> torch.Tensor:
        """Weak-perspective ``[s, tx, ty]`` best matching the true projection in the crop."""
        body = self.body
        with torch.no_grad():
            posed = body(self.scene.betas[None], self.scene.body_pose[None],
                         self.scene.global_orient[None])  # fmt: skip
        points = (posed.keypoints - posed.joints[:, :1])[0].double().numpy()
        ndc = pixels_to_ndc(torch.from_numpy(self.crop.image_to_crop(self.scene.keypoints2d)))
        ndc = ndc.numpy()
        # ndc = s * X + (s * t): solve for s and s * t jointly by least squares.
        rows = np.zeros((34, 3))
        rows[:17, 0], rows[:17, 1] = points[:, 0], 1.0
        rows[17:, 0], rows[17:, 2] = points[:, 1], 1.0
        solution = np.linalg.lstsq(rows, np.concatenate([ndc[:, 0], ndc[:, 1]]), rcond=None)[0]
        scale = solution[0]
        return torch.tensor([scale, solution[1] / scale, solution[2] / scale], dtype=torch.float32)

    def predict(
        self,
        image: np.ndarray,
        occluders: Sequence[Sequence[float]],
        evidence: bool = True,
        bbox: Sequence[float] | None = None,
    ) -> PredictionResult:
        self.calls += 1
        boxes = [tuple(map(float, b)) for b in occluders]
        covered = covered_keypoints(self.scene.keypoints2d, boxes)
        hidden = {COCO[i] for i in np.flatnonzero(covered)}
        levels = torch.full((len(BODY_JOINT_NAMES),), VISIBLE_CONCENTRATION)
        for joint, evidence in EVIDENCE.items():
            if hidden.intersection(evidence):
                levels[BODY_JOINT_NAMES.index(joint)] *= OCCLUDED_FACTOR
        singular = levels[:, None] * torch.tensor(AXIS_PROFILE)[None]
        F = self.scene.body_pose @ torch.diag_embed(singular)  # U = true rotation, V = I
        confidences = np.where(covered, 0.05, 0.95)
        painted = apply_occluders(np.asarray(image), boxes) if boxes else np.asarray(image)
        proxy = build_proxy(
            self.crop.crop_image(painted), self.crop.image_to_crop(self.scene.keypoints2d),
            confidences,
        )  # fmt: skip
        posterior = BodyPosterior(
            distribution=BodyDistribution(
                F=F,
                shape_mean=self.scene.betas.clone(),
                shape_std=torch.full_like(self.scene.betas, 0.08),
                global_orient=self.scene.global_orient,
                camera=self.camera,
            ),
            crop=self.crop,
            keypoints=torch.from_numpy(self.scene.keypoints2d).float(),
            confidences=torch.from_numpy(confidences).float(),
            body=self.body,
        )
        return PredictionResult(posterior=posterior, proxy=proxy)


# ---------------------------------------------------------------------- checks of the double


def test_double_mode_reprojects_onto_the_true_keypoints():
    double = OcclusionAwareDouble()
    result = double.predict(double.scene.image, [])
    reprojected = result.posterior.mode().keypoints2d[0].numpy()
    error = np.linalg.norm(reprojected - double.scene.keypoints2d, axis=1)
    assert error.max() < 15.0, error  # weak perspective vs the true perspective camera
    assert result.proxy is not None and result.proxy.shape == (18, 256, 256)


def test_double_lowers_concentration_only_for_joints_whose_evidence_is_covered():
    double = OcclusionAwareDouble()
    wrist = double.scene.keypoints2d[COCO.index("left_wrist")]
    box = (wrist[0] - 10, wrist[1] - 10, wrist[0] + 10, wrist[1] + 10)
    free = double.predict(double.scene.image, []).posterior.pose_distribution.concentration[0]
    hidden = double.predict(double.scene.image, [box]).posterior.pose_distribution.concentration
    ratio = (hidden[0] / free)[:, 0]
    lowered = {BODY_JOINT_NAMES[i] for i in np.flatnonzero(ratio.numpy() < 0.5)}
    assert lowered == {"left_elbow", "left_wrist", "left_hand"}
