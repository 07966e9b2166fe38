"""The supplement's augmentations of synthetic inputs, batched and driven by a torch generator.

Image-space augmentations return a boolean mask of the pixels they hide (for visibility) and
what to paint there; keypoint augmentations change only the *input* heatmaps, never the loss
targets.

| augmentation | setting (at 256 px) |
|---|---|
| body-part occlusion (24 parts) | p = 0.1 |
| left/right joint swap | p = 0.1 |
| half-image occlusion | p = 0.05 |
| 2D joint removal | p = 0.1 per joint |
| 2D joint noise | uniform in ±8 px |
| occlusion box | p = 0.5, 48 px |
| bounding-box scale | 0.8 - 1.2 |
| limb box (hkpd addition, off by default) | p = ``limb_occlusion_probability``, margin 6 px |

The limb box is not in the paper: it covers one limb segment's whole extent, the way a user
hides a limb with the explorer's occluders, so that the network sees hidden limbs often.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import torch

from hkpd.coco_keypoints import COCO17_LEFT_RIGHT_PAIRS
from hkpd.kinematic_tree import LIMB_SEGMENT_PARTS, SMPL_JOINT_NAMES


@dataclass(frozen=True)
class AugmentationConfig:
    """Probabilities and sizes of the augmentations; sizes are in pixels of a 256 crop and scale
    with the crop size."""

    body_part_occlusion_probability: float = 0.1
    max_occluded_parts: int = 3
    left_right_swap_probability: float = 0.1
    half_image_occlusion_probability: float = 0.05
    joint_removal_probability: float = 0.1
    joint_noise_px: float = 8.0
    occlusion_box_probability: float = 0.5
    occlusion_box_px: float = 48.0
    bbox_scale_range: tuple[float, float] = (0.8, 1.2)
    limb_occlusion_probability: float = 0.0
    limb_box_margin_px: float = 6.0
    keypoint_noise_sigma: float = 0.0
    keypoint_outlier_probability: float = 0.0
    keypoint_outlier_scale: float = 0.2

    @staticmethod
    def disabled() -> AugmentationConfig:
        """No augmentation at all (a clean image with exact heatmaps; bounding-box scale 1)."""
        return AugmentationConfig(0.0, 0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, (1.0, 1.0))


def _uniform(count: int, generator: torch.Generator, device: torch.device) -> torch.Tensor:
    return torch.rand(count, generator=generator).to(device)


def body_part_occlusion(
    part_map: torch.Tensor, config: AugmentationConfig, generator: torch.Generator
) -> torch.Tensor:
    """Pick, for a fraction of images, 1..``max_occluded_parts`` of the 24 parts to erase.

    Args:
        part_map: ``(B, H, W)`` long, -1 on background.

    Returns:
        ``(B, H, W)`` bool: pixels of erased parts (to be replaced by the background).
    """
    count, device = part_map.shape[0], part_map.device
    chosen = _uniform(count, generator, device) < config.body_part_occlusion_probability
    most = max(config.max_occluded_parts, 1)
    how_many = torch.randint(1, most + 1, (count,), generator=generator)
    ranks = torch.rand(count, 24, generator=generator).argsort(-1).argsort(-1)
    erased_parts = (ranks < how_many[:, None]).to(device) & chosen[:, None]  # (B, 24)
    table = torch.cat([torch.zeros(count, 1, dtype=torch.bool, device=device), erased_parts], 1)
    return table.gather(1, (part_map + 1).reshape(count, -1)).reshape(part_map.shape)


def half_image_occlusion(
    count: int, size: int, config: AugmentationConfig, generator: torch.Generator, device
) -> torch.Tensor:
    """Blank one half (top, bottom, left or right) of a fraction of images.

    Returns:
        ``(B, S, S)`` bool, the blanked pixels (painted black, like a crop past the photo edge).
    """
    chosen = _uniform(count, generator, device) < config.half_image_occlusion_probability
    side = torch.randint(0, 4, (count,), generator=generator).to(device)
    first_half = torch.arange(size, device=device) < size // 2  # (S,)
    # Per image a row mask and a column mask; the blanked region is their outer product.
    by_rows = side < 2  # sides 0/1: top/bottom rows; sides 2/3: left/right columns
    keep_first = (side % 2 == 0)[:, None]
    half_mask = torch.where(keep_first, first_half, ~first_half)  # (B, S)
    everything = torch.ones_like(half_mask)
    rows = torch.where(by_rows[:, None], half_mask, everything) & chosen[:, None]
    cols = torch.where(by_rows[:, None], everything, half_mask)
    return rows[:, :, None] & cols[:, None, :]


def occlusion_boxes(
    count: int, size: int, config: AugmentationConfig, generator: torch.Generator, device
) -> tuple[torch.Tensor, torch.Tensor]:
    """A square box of ``occlusion_box_px`` (scaled to the crop) at a random place, for a
    fraction of images.

    Returns:
        ``mask (B, S, S)`` bool and ``colour (B, 3)`` in [0, 1], a random solid colour per box.
    """
    chosen = _uniform(count, generator, device) < config.occlusion_box_probability
    side = max(1, round(config.occlusion_box_px * size / 256))
    corner = torch.randint(-side // 2, size - side // 2, (count, 2), generator=generator)
    corner = corner.to(device)
    index = torch.arange(size, device=device)
    rows_in = (index.view(1, -1) >= corner[:, 1:]) & (index.view(1, -1) < corner[:, 1:] + side)
    cols_in = (index.view(1, -1) >= corner[:, :1]) & (index.view(1, -1) < corner[:, :1] + side)
    mask = rows_in.unsqueeze(-1) & cols_in.unsqueeze(-2) & chosen.view(-1, 1, 1)
    colour = torch.rand(count, 3, generator=generator).to(device)
    return mask, colour


@functools.cache
def _limb_part_table() -> torch.Tensor:
    """``(limbs, 25)`` bool: ``table[l, p + 1]`` says part p belongs to limb segment l."""
    table = torch.zeros(len(LIMB_SEGMENT_PARTS), 25, dtype=torch.bool)
    for limb, parts in enumerate(LIMB_SEGMENT_PARTS.values()):
        table[limb, [SMPL_JOINT_NAMES.index(part) + 1 for part in parts]] = True
    return table


def _span(mask: torch.Tensor, margin: int) -> torch.Tensor:
    """``(B, S)`` bool to the run from its first to its last True, widened by ``margin``
    (all False where ``mask`` is)."""
    size = mask.shape[1]
    index = torch.arange(size, device=mask.device)
    first = torch.where(mask, index, size).amin(1, keepdim=True)
    last = torch.where(mask, index, -1).amax(1, keepdim=True)
    return (index >= first - margin) & (index <= last + margin) & mask.any(1, keepdim=True)


def limb_occlusion_boxes(
    part_map: torch.Tensor, config: AugmentationConfig, generator: torch.Generator
) -> tuple[torch.Tensor, torch.Tensor]:
    """Cover one random limb segment (:data:`hkpd.kinematic_tree.LIMB_SEGMENT_PARTS`) of a
    fraction of images with its bounding box plus ``limb_box_margin_px``.

    Half of the boxes are black (like the explorer's occluders), half a random solid colour.
    With ``limb_occlusion_probability == 0`` nothing is drawn from ``generator``, so data streams
    without this augmentation are unchanged.

    Args:
        part_map: ``(B, S, S)`` long body part per pixel, -1 on background.

    Returns:
        ``mask (B, S, S)`` bool (empty where no box, or where the limb is out of view) and
        ``colour (B, 3)`` in [0, 1].
    """
    count, size, device = part_map.shape[0], part_map.shape[-1], part_map.device
    if config.limb_occlusion_probability <= 0:
        empty = torch.zeros(part_map.shape, dtype=torch.bool, device=device)
        return empty, torch.zeros(count, 3, device=device)
    chosen = _uniform(count, generator, device) < config.limb_occlusion_probability
    limb = torch.randint(0, len(LIMB_SEGMENT_PARTS), (count,), generator=generator)
    colour = torch.rand(count, 3, generator=generator)
    colour = (colour * (torch.rand(count, 1, generator=generator) < 0.5)).to(device)
    parts = _limb_part_table()[limb].to(device) & chosen[:, None]  # (B, 25)
    on_limb = parts.gather(1, (part_map + 1).reshape(count, -1)).reshape(part_map.shape)
    margin = max(1, round(config.limb_box_margin_px * size / 256))
    rows, cols = _span(on_limb.any(2), margin), _span(on_limb.any(1), margin)
    return rows[:, :, None] & cols[:, None, :], colour


def swap_left_right(
    keypoints: torch.Tensor, config: AugmentationConfig, generator: torch.Generator
) -> torch.Tensor:
    """Swap the left and right shoulders, elbows, wrists, hips, knees and ankles of a fraction
    of the input keypoints (as a 2D detector sometimes does).

    Args:
        keypoints: ``(B, 17, 2)``; also works for ``(B, 17)`` per-joint flags.
    """
    count = keypoints.shape[0]
    chosen = _uniform(count, generator, keypoints.device) < config.left_right_swap_probability
    order = torch.arange(17, device=keypoints.device)
    for left, right in COCO17_LEFT_RIGHT_PAIRS:
        order[left], order[right] = right, left
    swapped = keypoints[:, order]
    shape = (-1,) + (1,) * (keypoints.dim() - 1)
    return torch.where(chosen.view(shape), swapped, keypoints)


def remove_joints(
    present: torch.Tensor, config: AugmentationConfig, generator: torch.Generator
) -> torch.Tensor:
    """Drop each input joint with ``joint_removal_probability``. ``present``: ``(B, 17)`` bool."""
    dropped = torch.rand(present.shape, generator=generator).to(present.device)
    return present & (dropped >= config.joint_removal_probability)


def jitter_joints(
    keypoints: torch.Tensor, size: int, config: AugmentationConfig, generator: torch.Generator
) -> torch.Tensor:
    """Add noise to each input keypoint: uniform in ±``joint_noise_px`` (scaled to the crop),
    or, with ``keypoint_noise_sigma > 0``, detector-like noise: a Gaussian of that standard
    deviation (fraction of the crop side) plus ``keypoint_outlier_probability`` outliers
    displaced uniformly by up to ``keypoint_outlier_scale`` of the crop
    (:mod:`hkpd.synthesis.detector_noise`)."""
    if config.keypoint_noise_sigma <= 0:
        amplitude = config.joint_noise_px * size / 256
        noise = (torch.rand(keypoints.shape, generator=generator) * 2 - 1) * amplitude
        return keypoints + noise.to(keypoints.device, keypoints.dtype)
    noise = torch.randn(keypoints.shape, generator=generator) * config.keypoint_noise_sigma * size
    outlier = torch.rand(keypoints.shape[:-1], generator=generator)
    outlier = outlier < config.keypoint_outlier_probability
    offset = torch.rand(keypoints.shape, generator=generator) * 2 - 1
    noise = torch.where(outlier[..., None], offset * config.keypoint_outlier_scale * size, noise)
    return keypoints + noise.to(keypoints.device, keypoints.dtype)
