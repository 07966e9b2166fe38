"""Which ground-truth keypoints a synthetic image really shows.

A keypoint is visible when it lies inside the crop, no augmentation occluder covers it, and the
body itself does not hide it. Self-occlusion is decided at the keypoint's pixel: the keypoint is
visible when that pixel shows one of the keypoint's own body parts (COCO keypoints sit inside
the body, so the surface in front of them belongs to their own limb), shows background, or the
rendered surface there is no more than ``depth_tolerance`` in front of the keypoint.
"""

from __future__ import annotations

import functools

import torch

from hkpd.coco_keypoints import COCO17_LEFT_RIGHT_PAIRS, COCO17_NAMES
from hkpd.kinematic_tree import SMPL_JOINT_NAMES

__all__ = [
    "COCO17_LEFT_RIGHT_PAIRS",
    "COCO17_NAMES",
    "COCO17_OWN_PARTS",
    "keypoint_visibility",
    "own_part_table",
]

_PART = {name: index for index, name in enumerate(SMPL_JOINT_NAMES)}


def _parts(*names: str) -> tuple[int, ...]:
    return tuple(_PART[name] for name in names)


def _sided(side: str) -> dict[str, tuple[int, ...]]:
    return {
        f"{side}_eye": _parts("head", "neck"),
        f"{side}_ear": _parts("head", "neck"),
        f"{side}_shoulder": _parts(f"{side}_collar", f"{side}_shoulder", "spine3"),
        f"{side}_elbow": _parts(f"{side}_shoulder", f"{side}_elbow"),
        f"{side}_wrist": _parts(f"{side}_elbow", f"{side}_wrist", f"{side}_hand"),
        f"{side}_hip": _parts("pelvis", f"{side}_hip"),
        f"{side}_knee": _parts(f"{side}_hip", f"{side}_knee"),
        f"{side}_ankle": _parts(f"{side}_knee", f"{side}_ankle", f"{side}_foot"),
    }


_OWN_PARTS = {"nose": _parts("head", "neck"), **_sided("left"), **_sided("right")}
COCO17_OWN_PARTS: tuple[tuple[int, ...], ...] = tuple(_OWN_PARTS[name] for name in COCO17_NAMES)
"""Per COCO keypoint, the body parts (SMPL joint groups) whose surface may cover it."""


@functools.cache
def own_part_table(num_parts: int = 24, device: torch.device | None = None) -> torch.Tensor:
    """``(17, num_parts + 1)`` bool: ``table[k, p + 1]`` says part p may cover keypoint k.

    Column 0 stands for background (part -1) and is True: a keypoint over background is seen.
    Built once per device (cached); do not modify the returned tensor.
    """
    table = torch.zeros(len(COCO17_NAMES), num_parts + 1, dtype=torch.bool, device=device)
    table[:, 0] = True
    for keypoint, parts in enumerate(COCO17_OWN_PARTS):
        table[keypoint, torch.tensor(parts) + 1] = True
    return table


def keypoint_visibility(
    keypoints: torch.Tensor,
    keypoint_depth: torch.Tensor,
    depth_map: torch.Tensor,
    part_map: torch.Tensor,
    occluded: torch.Tensor,
    depth_tolerance: float = 0.1,
) -> torch.Tensor:
    """Visibility of each keypoint in a rendered, augmented crop.

    Args:
        keypoints: ``(B, 17, 2)`` crop pixels.
        keypoint_depth: ``(B, 17)`` camera-frame depth of each keypoint, metres.
        depth_map: ``(B, H, W)`` rendered depth, metres (+inf on background).
        part_map: ``(B, H, W)`` long body part per pixel, -1 on background.
        occluded: ``(B, H, W)`` bool, pixels hidden by augmentations (boxes, removed parts,
            half-image blanking).
        depth_tolerance: metres; how far in front of the keypoint a foreign surface may lie.

    Returns:
        ``(B, 17)`` bool.
    """
    count, height, width = depth_map.shape
    pixel = keypoints.round().long()
    inside = (
        (pixel[..., 0] >= 0)
        & (pixel[..., 0] < width)
        & (pixel[..., 1] >= 0)
        & (pixel[..., 1] < height)
    )
    flat = pixel[..., 1].clamp(0, height - 1) * width + pixel[..., 0].clamp(0, width - 1)
    surface_depth = depth_map.reshape(count, -1).gather(1, flat)
    surface_part = part_map.reshape(count, -1).gather(1, flat)
    hidden_by_occluder = occluded.reshape(count, -1).gather(1, flat)
    table = own_part_table(device=keypoints.device)
    own_part = table[torch.arange(table.shape[0], device=keypoints.device), surface_part + 1]
    not_in_front = surface_depth >= keypoint_depth - depth_tolerance
    return inside & ~hidden_by_occluder & (own_part | not_in_front)
