"""Augmentation probabilities, masks and keypoint visibility logic."""

from __future__ import annotations

import torch

from hkpd.kinematic_tree import LIMB_SEGMENT_PARTS, SMPL_JOINT_NAMES
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
from hkpd.synthesis.visibility import COCO17_NAMES, keypoint_visibility, own_part_table

CONFIG = AugmentationConfig()
N = 4000


def generator(seed: int = 0) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


def tolerance(p: float) -> float:
    return 4 * (p * (1 - p) / N) ** 0.5


def test_occlusion_box_rate_and_size() -> None:
    mask, colour = occlusion_boxes(N, 64, CONFIG, generator(), "cpu")
    has_box = mask.flatten(1).any(1).float()
    # A box may fall partly outside; a fully outside box is impossible by construction.
    assert abs(float(has_box.mean()) - 0.5) < tolerance(0.5)
    assert int(mask.flatten(1).sum(1).max()) == 12 * 12  # 48 px at 256 -> 12 px at 64
    assert colour.shape == (N, 3)


def test_half_image_rate_and_extent() -> None:
    mask = half_image_occlusion(N, 32, CONFIG, generator(1), "cpu")
    blanked = mask.flatten(1).any(1)
    assert abs(float(blanked.float().mean()) - 0.05) < tolerance(0.05)
    assert set(mask.flatten(1).sum(1)[blanked].tolist()) == {32 * 16}
    rows = torch.arange(32)[:, None].expand(32, 32)
    cols = torch.arange(32)[None, :].expand(32, 32)
    halves = [rows < 16, rows >= 16, cols < 16, cols >= 16]  # top, bottom, left, right
    seen = set()
    for image_mask in mask[blanked]:
        matches = [k for k, half in enumerate(halves) if torch.equal(image_mask, half)]
        assert len(matches) == 1
        seen.add(matches[0])
    assert seen == {0, 1, 2, 3}


def test_body_part_occlusion_rate_and_only_body_pixels() -> None:
    part_map = torch.randint(-1, 24, (N, 8, 8), generator=generator(2))
    erased = body_part_occlusion(part_map, CONFIG, generator(3))
    assert not bool(erased[part_map == -1].any())
    touched = erased.flatten(1).any(1).float().mean()
    assert abs(float(touched) - 0.1) < tolerance(0.1) + 0.01  # tiny maps may miss a part
    # Erasing is per part: an erased image erases every pixel of the chosen parts.
    index = int(erased.flatten(1).any(1).nonzero()[0])
    parts = part_map[index][erased[index]].unique()
    assert bool(erased[index][torch.isin(part_map[index], parts)].all())


def test_swap_rate_and_pairs() -> None:
    keypoints = torch.arange(17.0).view(1, 17, 1).expand(N, 17, 2).clone()
    swapped = swap_left_right(keypoints, CONFIG, generator(4))
    changed = (swapped != keypoints).flatten(1).any(1)
    assert abs(float(changed.float().mean()) - 0.1) < tolerance(0.1)
    row = swapped[changed][0, :, 0]
    assert row[5] == 6 and row[6] == 5 and row[15] == 16 and row[0] == 0 and row[1] == 1


def test_joint_removal_rate_and_noise_range() -> None:
    present = torch.ones(N, 17, dtype=torch.bool)
    kept = remove_joints(present, CONFIG, generator(5))
    assert abs(1 - float(kept.float().mean()) - 0.1) < 0.01
    jittered = jitter_joints(torch.zeros(N, 17, 2), 256, CONFIG, generator(6))
    assert float(jittered.abs().max()) <= 8.0 and float(jittered.abs().max()) > 7.5
    assert abs(float(jittered.mean())) < 0.1


def test_disabled_config_changes_nothing() -> None:
    off = AugmentationConfig.disabled()
    assert not bool(occlusion_boxes(50, 32, off, generator(), "cpu")[0].any())
    keypoints = torch.rand(50, 17, 2)
    torch.testing.assert_close(swap_left_right(keypoints, off, generator()), keypoints)
    torch.testing.assert_close(jitter_joints(keypoints, 32, off, generator()), keypoints)


def test_visibility_logic() -> None:
    wrist = COCO17_NAMES.index("left_wrist")
    assert bool(own_part_table()[wrist, 1 + 18])  # the left forearm (left_elbow group) covers it
    size = 16
    depth = torch.full((1, size, size), float("inf"))
    parts = torch.full((1, size, size), -1)
    depth[0, :, :8] = 2.0  # the left half shows the torso (spine3) at 2 m
    parts[0, :, :8] = 9
    occluded = torch.zeros(1, size, size, dtype=torch.bool)
    occluded[0, 12:, 12:] = True
    keypoints = torch.full((1, 17, 2), 10.0)
    keypoint_depth = torch.full((1, 17), 2.05)
    keypoints[0, 0] = torch.tensor([4.0, 4.0])  # nose behind the torso, within tolerance
    keypoint_depth[0, 1] = 2.5
    keypoints[0, 1] = torch.tensor([4.0, 4.0])  # left eye 50 cm behind the torso: hidden
    keypoints[0, 2] = torch.tensor([14.0, 14.0])  # under the occluder
    keypoints[0, 3] = torch.tensor([-1.0, 3.0])  # outside the crop
    keypoint_depth[0, 5] = 2.5
    keypoints[0, 5] = torch.tensor([4.0, 4.0])  # left shoulder behind spine3: its own part
    visible = keypoint_visibility(keypoints, keypoint_depth, depth, parts, occluded)
    assert visible[0].tolist()[:6] == [True, False, False, False, True, True]
    assert bool(visible[0, 6:].all())  # over background at (10, 10)


def test_limb_box_off_draws_nothing_and_covers_nothing() -> None:
    part_map = torch.randint(-1, 24, (8, 32, 32))
    rng = generator(3)
    mask, _ = limb_occlusion_boxes(part_map, CONFIG, rng)
    assert not mask.any()
    assert torch.equal(rng.get_state(), generator(3).get_state())


def limb_pixels(part_map: torch.Tensor, limb: str) -> torch.Tensor:
    parts = torch.tensor([SMPL_JOINT_NAMES.index(part) for part in LIMB_SEGMENT_PARTS[limb]])
    return torch.isin(part_map, parts)


def test_limb_box_covers_exactly_one_whole_limb_segment() -> None:
    # Each image: a rectangle of every limb part at a distinct place, the rest background.
    count, size = 64, 64
    part_map = torch.full((count, size, size), -1)
    limbs = list(LIMB_SEGMENT_PARTS)
    spots = {}
    for index, limb in enumerate(limbs):
        row, col = 4 + 7 * index, 4 + 6 * index
        for offset, part in enumerate(LIMB_SEGMENT_PARTS[limb]):
            part_map[:, row : row + 3, col + 2 * offset : col + 2 * offset + 2] = (
                SMPL_JOINT_NAMES.index(part)
            )
        spots[limb] = (row, col)
    config = AugmentationConfig(limb_occlusion_probability=1.0, limb_box_margin_px=0.0)
    mask, colour = limb_occlusion_boxes(part_map, config, generator(4))
    assert colour.shape == (count, 3) and (colour.sum(1) == 0).any()  # some boxes black
    covered_limbs = set()
    for image in range(count):
        share = {limb: float(mask[image][limb_pixels(part_map[image], limb)].float().mean())
                 for limb in limbs}  # fmt: skip
        (limb,) = [limb for limb, value in share.items() if value == 1.0]
        assert sum(share.values()) == 1.0  # no pixel of any other limb is covered
        covered_limbs.add(limb)
        rows, cols = mask[image].any(1).nonzero(), mask[image].any(0).nonzero()
        box = mask[image][rows.min() : rows.max() + 1, cols.min() : cols.max() + 1]
        assert box.all() and int(mask[image].sum()) == box.numel()  # one solid rectangle
    assert covered_limbs == set(limbs)


def test_limb_box_rate() -> None:
    part_map = torch.zeros(N, 8, 8, dtype=torch.long)
    part_map[:] = torch.arange(24).repeat(3)[:64].view(8, 8)
    config = AugmentationConfig(limb_occlusion_probability=0.3)
    mask, _ = limb_occlusion_boxes(part_map, config, generator(5))
    assert abs(float(mask.flatten(1).any(1).float().mean()) - 0.3) < tolerance(0.3)
