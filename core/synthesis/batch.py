"""The training batch: what the synthetic data generator yields and the training loop consumes."""

from __future__ import annotations

from dataclasses import dataclass, fields

import torch

from hkpd.proxy import assemble_proxy


@dataclass
class BatchTargets:
    """The ground truth of a batch of synthetic examples, shared by :class:`TrainingBatch` and
    :class:`PackedBatch`; all tensors on the same device.

    Coordinates follow :mod:`hkpd.camera_conventions` (OpenCV camera frame, 256-pixel crops).

    Attributes:
        body_pose: ``(B, 23, 3, 3)`` ground-truth relative rotations of the 23 body joints.
        global_orient: ``(B, 3, 3)`` body-to-camera rotation.
        betas: ``(B, 10)`` ground-truth shape coefficients.
        keypoints2d: ``(B, 17, 2)`` ground-truth COCO keypoints in crop pixels (before 2D noise
            and swaps: the loss target).
        visible: ``(B, 17)`` bool, keypoint inside the crop and not hidden by the body or an
            occluder.
        joints3d: ``(B, 24, 3)`` ground-truth joints in the camera frame, metres.
        translation: ``(B, 3)`` camera-frame translation of the body's root, metres.
        focal_px: ``(B,)`` perspective focal length in pixels.
    """

    body_pose: torch.Tensor
    global_orient: torch.Tensor
    betas: torch.Tensor
    keypoints2d: torch.Tensor
    visible: torch.Tensor
    joints3d: torch.Tensor
    translation: torch.Tensor
    focal_px: torch.Tensor

    def targets_on(self, device: torch.device | str) -> dict[str, torch.Tensor]:
        """The ground-truth fields by name, moved to ``device``."""
        return {f.name: getattr(self, f.name).to(device) for f in fields(BatchTargets)}


@dataclass
class TrainingBatch(BatchTargets):
    """One batch of synthetic training examples: the network input plus :class:`BatchTargets`.

    Attributes:
        proxy: ``(B, C + 17, 256, 256)`` float32: the image proxy's ``C`` channels (the edge
            image in {0, 1} by default; :mod:`hkpd.proxy.representation`), then the COCO-17
            joint heatmaps (zero where a joint was dropped).
        The others: as in :class:`BatchTargets`.
    """

    proxy: torch.Tensor

    @property
    def batch_size(self) -> int:
        return int(self.proxy.shape[0])

    def to(self, device: torch.device | str) -> TrainingBatch:
        """A copy with every tensor on ``device``."""
        return TrainingBatch(proxy=self.proxy.to(device), **self.targets_on(device))


@dataclass
class PackedBatch(BatchTargets):
    """A :class:`TrainingBatch` before its heatmaps are drawn: what crosses process boundaries.

    The float proxy of a 256-px example is 4.7 MB, almost all of it Gaussian heatmaps that are
    cheap to draw from 17 points; its uint8 edge image is 64 KB. Worker processes therefore send
    this and the consumer calls :meth:`unpack`, which gives exactly the batch the generator
    would have made in one process.

    Attributes:
        image_planes: ``(B, C, S, S)`` uint8 image proxy in [0, 255] (Canny edges as 0/255 by
            default; :func:`hkpd.proxy.image_planes_batch`).
        input_keypoints: ``(B, 17, 2)`` the keypoints the heatmaps are drawn at (augmented).
        input_present: ``(B, 17)`` bool, which of them are drawn.
        The others: as in :class:`BatchTargets`.
    """

    image_planes: torch.Tensor
    input_keypoints: torch.Tensor
    input_present: torch.Tensor

    def unpack(self, device: torch.device | str | None = None) -> TrainingBatch:
        """The training batch, its proxy drawn on ``device`` (default: the keypoints' device)."""
        device = self.input_keypoints.device if device is None else torch.device(device)
        proxy = assemble_proxy(self.image_planes, self.input_keypoints, self.input_present, device)
        return TrainingBatch(proxy=proxy, **self.targets_on(device))
