"""The synthetic data generator: poses and shapes -> posed bodies -> rendered crops ->
augmentations -> proxy representations with ground truth.

One batch, step by step (settings from the paper's supplement):

1. Relative joint rotations and a world orientation come from a pose source (a mocap pose
   bank or the procedural prior); shapes are drawn from ``N(0, 1.25²)``.
2. The body is turned by a random heading about the vertical and seen by an upright camera:
   ``global_orient = FRONTAL_GLOBAL_ORIENT @ R_y(yaw) @ world_orient``. The pelvis is placed at
   a camera translation sampled as in the supplement (mean 2.5 m away).
3. A square box around the projected keypoints (margin ``CROP_MARGIN``, times a random scale in
   0.8-1.2) becomes the crop. Rather than rendering a large frame and resampling, the crop is
   rendered directly: the focal length is scaled by ``crop size / box side`` and the box's
   offset from the optical axis becomes a shear ``x' = x + d z / f'`` of the camera-frame
   vertices, which moves every projection by exactly ``d`` pixels and leaves depth unchanged.
4. The mesh is rendered with a random clothing texture and lighting over a background, then
   the image-space augmentations are applied (body-part erasing, an occluding box, half-image
   blanking) and keypoint visibility is decided (:mod:`hkpd.synthesis.visibility`).
5. The input keypoints get the keypoint augmentations (left/right swap, removal, ±8 px noise);
   the loss targets keep the exact ones. Edges and heatmaps form the proxy (or, for the proxy
   ablation, the body's silhouette minus what occluders hide, or the RGB image, instead of the
   edges). The ``"edges+mask"`` proxy adds a detector-like person mask
   (:func:`hkpd.synthesis.mask_noise.detector_like_masks` of the silhouette minus what
   occluders hide, zero in occluded pixels; all zero, "no mask", in a share of the examples).

Every random draw comes from one CPU ``torch.Generator`` seeded per batch, so a batch depends
only on ``(seed, batch index)``: the same on CPU and CUDA, and a fixed test set is regenerated
exactly.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import roma
import torch

from hkpd.body import BodyModel
from hkpd.camera_conventions import (
    CROP_SIZE,
    FRONTAL_GLOBAL_ORIENT,
    perspective_project,
)
from hkpd.poses import PoseSource
from hkpd.proxy import (
    CROP_MARGIN,
    DEFAULT_IMAGE_PROXY,
    image_planes_batch,
    image_proxy_channels,
    square_box_around_keypoints,
)
from hkpd.rendering import (
    BackgroundSource,
    ClothingTextureSampler,
    MeshRenderer,
    RenderOutput,
    sample_cameras,
    sample_lighting,
)
from hkpd.synthesis.augmentations import (
    AugmentationConfig,
    body_part_occlusion,
    half_image_occlusion,
    jitter_joints,
    limb_occlusion_boxes,
    occlusion_boxes,
    remove_joints,
    swap_left_right,
)
from hkpd.synthesis.batch import PackedBatch, TrainingBatch
from hkpd.synthesis.mask_noise import MaskNoise, detector_like_masks
from hkpd.synthesis.orientation import UPRIGHT, OrientationMix, sample_view_rotation
from hkpd.synthesis.visibility import keypoint_visibility


@dataclass(frozen=True)
class SyntheticDataConfig:
    """Settings of the synthetic data.

    Attributes:
        image_size: side of the square crops in pixels (256 for training; smaller for tests).
        shape_std: standard deviation of the sampled shape coefficients.
        max_camera_pitch_deg: the camera tilts up or down by at most this much.
        augmentation: the supplement's augmentations.
        orientation: extra rolls and steep views (:mod:`hkpd.synthesis.orientation`); the
            default adds none (upright people, as in the paper).
        image_proxy: the image part of the network input (:data:`hkpd.proxy.IMAGE_PROXIES`):
            ``"edges"`` (hkpd's), ``"edges+mask"`` (edges and a detector-like person mask), or
            ``"silhouette"`` / ``"rgb"`` for the proxy ablation.
        mask_noise: how the ``"edges+mask"`` proxy's mask is degraded from the silhouette.
        mask_missing_probability: share of ``"edges+mask"`` examples whose mask plane is all
            zero (a detector that gave no mask), so that the network also reads without one.
    """

    image_size: int = CROP_SIZE
    shape_std: float = 1.25
    max_camera_pitch_deg: float = 10.0
    augmentation: AugmentationConfig = field(default_factory=AugmentationConfig)
    orientation: OrientationMix = UPRIGHT
    image_proxy: str = DEFAULT_IMAGE_PROXY
    mask_noise: MaskNoise = field(default_factory=MaskNoise)
    mask_missing_probability: float = 0.1

    def __post_init__(self) -> None:
        image_proxy_channels(self.image_proxy)  # raises on an unknown name
        if not 0.0 <= self.mask_missing_probability <= 1.0:
            raise ValueError(
                f"mask_missing_probability must be in [0, 1], got {self.mask_missing_probability}"
            )


@dataclass
class RenderedBatch:
    """A training batch together with the pictures it came from (for previews and tests).

    Attributes:
        batch: the training batch.
        images: ``(B, S, S, 3)`` uint8 RGB crops after image augmentations.
        part_map: ``(B, S, S)`` long body part per pixel (-1 background), before erasing.
        input_keypoints: ``(B, 17, 2)`` the keypoints drawn into the heatmaps (augmented).
        input_present: ``(B, 17)`` bool, which of them were drawn.
        occluded: ``(B, S, S)`` bool, pixels hidden by the occlusion augmentations (erased
            parts, boxes, half-image blanking).
    """

    batch: TrainingBatch
    images: np.ndarray
    part_map: torch.Tensor
    input_keypoints: torch.Tensor
    input_present: torch.Tensor
    occluded: torch.Tensor


@dataclass(frozen=True)
class _Scene:
    """The drawn people of one batch, camera frame (metres; the camera looks along +z).

    Attributes:
        body_pose: ``(B, 23, 3, 3)``; global_orient: ``(B, 3, 3)``; betas: ``(B, K)``.
        translation: ``(B, 3)`` the root joint's position; focal_full: ``(B,)`` the focal
            length in the full 256-px frame, pixels.
        vertices, joints3d, keypoints3d: ``(B, V, 3)``, ``(B, 24, 3)``, ``(B, 17, 3)``.
    """

    body_pose: torch.Tensor
    global_orient: torch.Tensor
    betas: torch.Tensor
    translation: torch.Tensor
    focal_full: torch.Tensor
    vertices: torch.Tensor
    joints3d: torch.Tensor
    keypoints3d: torch.Tensor


@dataclass(frozen=True)
class _CropCamera:
    """The camera of the crop: ``(B,)`` focal length and ``(B, 2)`` principal-point shift,
    pixels at ``size``."""

    focal: torch.Tensor
    shift: torch.Tensor
    size: int

    def to_crop_camera(self, points: torch.Tensor) -> torch.Tensor:
        """``(B, N, 3)`` points sheared so that the crop's centre projects to the middle."""
        shear = self.shift[:, None] * points[..., 2:] / self.focal[:, None, None]
        return torch.cat([points[..., :2] + shear, points[..., 2:]], -1)

    def project(self, points: torch.Tensor) -> torch.Tensor:
        """``(B, N, 2)`` crop pixels of ``(B, N, 3)`` camera-frame points."""
        return perspective_project(self.to_crop_camera(points), self.focal[:, None], self.size)


def batch_seed(seed: int, index: int) -> int:
    """The generator seed of batch ``index`` in the stream of ``seed``."""
    return (seed * 1_000_003 + index * 7_919 + 12_345) % (2**63 - 1)


class SyntheticDataGenerator:
    """Makes batches of synthetic training examples on a chosen device.

    Args:
        pose_source: where relative joint rotations and world orientations come from.
        config: image size, shape prior and augmentations.
        device: where rendering, the body model and the output tensors live.
        background_dir: optional folder of background images; procedural clutter otherwise.
        body: the body model (default: the shipped one).
    """

    def __init__(
        self,
        pose_source: PoseSource,
        config: SyntheticDataConfig | None = None,
        device: torch.device | str = "cpu",
        background_dir: Path | str | None = None,
        body: BodyModel | None = None,
    ) -> None:
        self.pose_source = pose_source
        self.config = config or SyntheticDataConfig()
        self.device = torch.device(device)
        self.body = (body or BodyModel()).to(self.device)
        faces = self.body.faces
        self.face_parts = self.body.part_labels[faces[:, 0]]
        self.renderer = MeshRenderer(faces, image_size=self.config.image_size, device=self.device)
        self.textures = ClothingTextureSampler(self.body.v_template, faces, self.body.part_labels)
        self.backgrounds = BackgroundSource(Path(background_dir) if background_dir else None)

    def generate(self, count: int, seed: int, betas: torch.Tensor | None = None) -> RenderedBatch:
        """One batch of ``count`` examples, fully determined by ``seed``.

        Args:
            count: examples in the batch.
            seed: the batch's seed.
            betas: optional ``(count, K)`` shape coefficients to use instead of drawn ones
                (e.g. several views of one body: the same betas under different seeds). Every
                other draw, the drawn betas included, is made as without it, so poses, cameras,
                clothing and augmentations are those of ``seed`` either way.
        """
        packed, images, part_map, occluded = self._make(count, seed, betas)
        return RenderedBatch(
            packed.unpack(), images, part_map, packed.input_keypoints, packed.input_present,
            occluded,
        )  # fmt: skip

    def generate_packed(
        self, count: int, seed: int, betas: torch.Tensor | None = None
    ) -> PackedBatch:
        """The batch :meth:`generate` makes for ``seed`` (and ``betas``), with its heatmaps not
        yet drawn (``generate_packed(n, s).unpack()`` equals ``generate(n, s).batch``)."""
        return self._make(count, seed, betas)[0]

    def _fixed_betas(self, betas: torch.Tensor, count: int) -> torch.Tensor:
        """``betas`` as a ``(count, K)`` float tensor on the device, or a ValueError."""
        betas = torch.as_tensor(betas)
        expected = (count, self.body.num_betas)
        if tuple(betas.shape) != expected:
            raise ValueError(f"betas must have shape {expected} for a batch of {count}, got "
                             f"{tuple(betas.shape)}")  # fmt: skip
        if not bool(torch.isfinite(betas).all()):
            raise ValueError("betas must be finite numbers")
        return betas.to(self.device, torch.float32)

    def _make(
        self, count: int, seed: int, fixed_betas: torch.Tensor | None = None
    ) -> tuple[PackedBatch, np.ndarray, torch.Tensor, torch.Tensor]:
        """The packed batch, its ``(B, S, S, 3)`` uint8 images, ``(B, S, S)`` part map and
        ``(B, S, S)`` occluded pixels (with ``fixed_betas`` instead of the drawn shapes when
        given)."""
        generator = torch.Generator().manual_seed(seed)
        config, augment = self.config, self.config.augmentation
        scene = self._draw_scene(count, generator, fixed_betas)
        camera = self._draw_crop_camera(scene, generator)
        keypoints2d = camera.project(scene.keypoints3d)
        rendered, image, part_map, occluded = self._render(scene, camera, generator)

        visible = keypoint_visibility(
            keypoints2d, scene.keypoints3d[..., 2], rendered.depth, part_map, occluded
        )
        input_present = remove_joints(visible, augment, generator)
        swapped_points = swap_left_right(
            torch.cat([keypoints2d, input_present[..., None]], -1), augment, generator
        )
        input_present = swapped_points[..., 2] > 0.5
        input_keypoints = jitter_joints(
            swapped_points[..., :2], config.image_size, augment, generator
        )

        pixels = image.mul_(255.0).add_(0.5).clamp_(0.0, 255.0).to(torch.uint8)
        images = pixels.permute(0, 2, 3, 1).contiguous().cpu().numpy()  # contiguous rows for cv2
        silhouettes = self._proxy_silhouettes(rendered.mask, occluded, generator)
        planes = image_planes_batch(images, config.image_proxy, silhouettes).to(self.device)
        packed = PackedBatch(
            image_planes=planes,
            input_keypoints=input_keypoints,
            input_present=input_present,
            body_pose=scene.body_pose,
            global_orient=scene.global_orient,
            betas=scene.betas,
            keypoints2d=keypoints2d,
            visible=visible,
            joints3d=scene.joints3d,
            translation=scene.translation,
            focal_px=camera.focal,
        )
        return packed, images, part_map, occluded

    def _proxy_silhouettes(
        self, body_mask: torch.Tensor, occluded: torch.Tensor, generator: torch.Generator
    ) -> torch.Tensor | None:
        """What the image proxy gets as ``silhouettes``: the ``(B, S, S)`` bool silhouette minus
        occluded pixels (``"silhouette"``), a float32 detector-like mask in [0, 1] that is zero
        where occluded and in the examples without a mask (``"edges+mask"``), or None."""
        proxy = self.config.image_proxy
        if proxy not in ("silhouette", "edges+mask"):
            return None
        visible = body_mask & ~occluded
        if proxy == "silhouette":
            return visible
        known = ~occluded
        masks = detector_like_masks(visible, known, self.config.mask_noise, generator)
        missing = torch.rand(masks.shape[0], generator=generator)
        missing = (missing < self.config.mask_missing_probability).to(masks.device)
        return torch.where(known & ~missing[:, None, None], masks, 0.0)

    def _draw_scene(
        self, count: int, generator: torch.Generator, fixed_betas: torch.Tensor | None
    ) -> _Scene:
        """Poses, view, shapes and cameras of ``count`` people, and their posed bodies."""
        config, device = self.config, self.device
        body_pose, world_orient = self.pose_source.sample(count, generator)
        body_pose, world_orient = body_pose.to(device).float(), world_orient.to(device).float()
        yaw = (torch.rand(count, generator=generator) * 2 - 1) * math.pi
        pitch = (torch.rand(count, generator=generator) * 2 - 1) * math.radians(
            config.max_camera_pitch_deg
        )
        zeros = torch.zeros(count)
        heading = roma.rotvec_to_rotmat(torch.stack([zeros, yaw, zeros], -1))  # about world up
        tilt = roma.rotvec_to_rotmat(torch.stack([pitch, zeros, zeros], -1))  # about camera x
        camera_rotation = tilt @ FRONTAL_GLOBAL_ORIENT @ heading
        view = sample_view_rotation(count, generator, config.orientation)
        if view is not None:
            camera_rotation = view @ camera_rotation
        global_orient = camera_rotation.to(device) @ world_orient
        betas = (
            torch.randn(count, self.body.num_betas, generator=generator) * config.shape_std
        ).to(device)  # drawn even when fixed: the random stream stays the same
        if fixed_betas is not None:
            betas = self._fixed_betas(fixed_betas, count)
        translation, focal_full = sample_cameras(count, generator, device)
        translation, focal_full = translation.float(), focal_full.float()

        with torch.no_grad():
            posed = self.body(betas, body_pose, global_orient)
        origin = posed.joints[:, :1] - translation[:, None]
        return _Scene(
            body_pose=body_pose,
            global_orient=global_orient,
            betas=betas,
            translation=translation,
            focal_full=focal_full,
            vertices=posed.vertices - origin,
            joints3d=posed.joints - origin,
            keypoints3d=posed.keypoints - origin,
        )

    def _draw_crop_camera(self, scene: _Scene, generator: torch.Generator) -> _CropCamera:
        """The crop: a square box around the keypoints projected in the full 256-px frame,
        scaled by the augmentation's random factor, seen at ``image_size`` pixels."""
        count, device = scene.keypoints3d.shape[0], self.device
        full_frame = torch.ones(count, scene.keypoints3d.shape[1], dtype=torch.bool, device=device)
        projected = perspective_project(scene.keypoints3d, scene.focal_full[:, None], CROP_SIZE)
        centre, side = square_box_around_keypoints(projected, full_frame, CROP_MARGIN)
        low, high = self.config.augmentation.bbox_scale_range
        side = side * (low + (high - low) * torch.rand(count, generator=generator)).to(device)
        zoom = self.config.image_size / side
        shift = (CROP_SIZE / 2 - centre) * zoom[:, None]  # pixels, in the crop
        return _CropCamera(scene.focal_full * zoom, shift, self.config.image_size)

    def _render(
        self, scene: _Scene, camera: _CropCamera, generator: torch.Generator
    ) -> tuple[RenderOutput, torch.Tensor, torch.Tensor, torch.Tensor]:
        """The rendering, the ``(B, 3, S, S)`` float image on its background after the
        occlusion augmentations, the ``(B, S, S)`` part map and the ``(B, S, S)`` occluded
        pixels."""
        count, size, device = scene.vertices.shape[0], self.config.image_size, self.device
        augment = self.config.augmentation
        lighting = sample_lighting(count, generator, device)
        colours = self.textures.sample(count, generator, device)
        vertices = camera.to_crop_camera(scene.vertices)
        rendered = self.renderer.render(vertices, camera.focal, colours, lighting)
        part_map = rendered.part_map(self.face_parts)
        background = self.backgrounds.sample(count, generator, size, device)

        erased = body_part_occlusion(part_map, augment, generator)
        box, box_colour = occlusion_boxes(count, size, augment, generator, device)
        half = half_image_occlusion(count, size, augment, generator, device)
        limb_box, limb_colour = limb_occlusion_boxes(part_map, augment, generator)
        image = torch.where((rendered.mask & ~erased)[:, None], rendered.rgb, background)
        # Boxes and half-image blanking touch few images: paint only those.
        for mask, colour in ((box, box_colour), (limb_box, limb_colour)):
            for index in mask.flatten(1).any(1).nonzero().flatten().tolist():
                region = mask[index]
                image[index] = torch.where(region, colour[index, :, None, None], image[index])
        for index in half.flatten(1).any(1).nonzero().flatten().tolist():
            image[index].masked_fill_(half[index], 0.0)
        return rendered, image, part_map, erased | box | half | limb_box


class SyntheticBatches:
    """An endless, deterministic stream of training batches (an iterable for training loops).

    Batch ``i`` depends only on ``(seed, i)``, so a stream resumes exactly at a step.

    Args:
        generator: the synthetic data generator.
        batch_size: examples per batch.
        seed: the stream's seed.
        start: the first batch index (for resuming).
    """

    def __init__(
        self, generator: SyntheticDataGenerator, batch_size: int, seed: int = 0, start: int = 0
    ) -> None:
        self.generator, self.batch_size, self.seed, self.start = generator, batch_size, seed, start

    def __iter__(self):
        index = self.start
        while True:
            yield self.generator.generate(self.batch_size, batch_seed(self.seed, index)).batch
            index += 1


def iter_fixed_test_set(
    generator: SyntheticDataGenerator, count: int = 1000, seed: int = 2021, batch_size: int = 50
) -> Iterator[TrainingBatch]:
    """The batches of :func:`fixed_test_set`, made one at a time (bounded memory)."""
    for index, start in enumerate(range(0, count, batch_size)):
        size = min(batch_size, count - start)
        yield generator.generate(size, batch_seed(seed, index)).batch


def fixed_test_set(
    generator: SyntheticDataGenerator, count: int = 1000, seed: int = 2021, batch_size: int = 50
) -> list[TrainingBatch]:
    """A fixed synthetic test set: ``count`` examples in batches, identical on every call.

    Use a generator whose pose source is the held-out *test* split of a pose bank.
    """
    return list(iter_fixed_test_set(generator, count, seed, batch_size))
