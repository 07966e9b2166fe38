"""Orientation, pose-family and detector-noise coverage of the synthetic data."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from hkpd.kinematic_tree import BODY_JOINT_NAMES
from hkpd.poses.archetypes import FAMILIES, WIDER_LIMITS, PoseArchetypes
from hkpd.poses.mixed_source import LEG_JOINTS, MixedPoseSource, PoseMix
from hkpd.poses.procedural import ProceduralPosePrior
from hkpd.synthesis.augmentations import AugmentationConfig, jitter_joints
from hkpd.synthesis.generator import SyntheticDataConfig, SyntheticDataGenerator
from hkpd.synthesis.orientation import (
    ANY_ORIENTATION,
    TRAINING_MIX,
    UPRIGHT,
    OrientationMix,
    image_tilt_degrees,
    sample_view_rotation,
)
from hkpd.training.config import TrainConfig


def _tilts(mix: OrientationMix, count: int = 120) -> np.ndarray:
    config = SyntheticDataConfig(image_size=32, orientation=mix,
                                 augmentation=AugmentationConfig.disabled())  # fmt: skip
    generator = SyntheticDataGenerator(ProceduralPosePrior(), config)
    batch = generator.generate(count, seed=5).batch
    return image_tilt_degrees(batch.keypoints2d).numpy()


def test_upright_mix_draws_nothing_and_keeps_people_upright() -> None:
    generator = torch.Generator().manual_seed(0)
    assert sample_view_rotation(4, generator, UPRIGHT) is None
    assert (
        torch.rand(1, generator=generator).item()
        == torch.rand(1, generator=torch.Generator().manual_seed(0)).item()
    )  # no random number was consumed
    assert (_tilts(UPRIGHT) > 30).mean() < 0.05


def test_training_mix_leans_a_third_and_the_any_split_covers_every_tilt() -> None:
    leaning = (_tilts(TRAINING_MIX, 200) > 30).mean()
    assert 0.22 < leaning < 0.45
    tilts = _tilts(ANY_ORIENTATION, 200)
    assert (tilts > 90).mean() > 0.3 and (tilts > 150).mean() > 0.08


def test_orientation_mix_rejects_bad_shares() -> None:
    with pytest.raises(ValueError, match="roll_probability"):
        OrientationMix(roll_probability=1.5)


def test_pose_families_stay_inside_the_joint_limits_and_all_appear() -> None:
    archetypes = PoseArchetypes()
    angles, family = archetypes.sample_angles(400, torch.Generator().manual_seed(1))
    low = torch.tensor([[r[0] for r in WIDER_LIMITS[n].ranges] for n in BODY_JOINT_NAMES])
    high = torch.tensor([[r[1] for r in WIDER_LIMITS[n].ranges] for n in BODY_JOINT_NAMES])
    assert ((angles >= low - 1e-4) & (angles <= high + 1e-4)).all()
    assert set(family.tolist()) == set(range(len(FAMILIES)))
    knees = [BODY_JOINT_NAMES.index(f"{side}_knee") for side in ("left", "right")]
    kneeling = family == [f.name for f in FAMILIES].index("kneeling upright")
    assert (angles[kneeling][:, knees, 0] >= 85 - 1e-4).all()
    body_pose, orient = archetypes.sample(8, torch.Generator().manual_seed(2))
    eye = torch.eye(3)
    assert torch.allclose(body_pose.transpose(-1, -2) @ body_pose, eye.expand_as(body_pose),
                          atol=1e-5)  # fmt: skip
    assert orient.shape == (8, 3, 3)


def test_mixed_source_shares_and_limb_mixes() -> None:
    class Counter:
        """A base source whose poses say which draw they came from."""

        def __init__(self) -> None:
            self.calls = 0

        def sample(self, count, generator):
            self.calls += 1
            angle = torch.full((count, 23, 3), 0.1 * self.calls)
            import roma

            return roma.rotvec_to_rotmat(angle), torch.eye(3).expand(count, 3, 3).clone()

    source = MixedPoseSource(Counter(), PoseMix(archetype_share=0.3, limb_mix_share=0.2))
    body_pose, _ = source.sample(2000, torch.Generator().manual_seed(0))
    first = body_pose[:, 0]
    import roma

    base = roma.rotvec_to_rotmat(torch.full((3,), 0.1))
    legs_second = roma.rotvec_to_rotmat(torch.full((3,), 0.2))
    plain = torch.isclose(body_pose[:, 2], base, atol=1e-6).flatten(1).all(1)  # spine1
    legs = torch.isclose(body_pose[:, LEG_JOINTS[0]], legs_second, atol=1e-6).flatten(1).all(1)
    assert abs(float(legs.float().mean()) - 0.2) < 0.04
    assert abs(float((~plain).float().mean()) - 0.3) < 0.04  # archetypes replace the spine
    del first
    with pytest.raises(ValueError, match="sum to at most 1"):
        PoseMix(archetype_share=0.8, limb_mix_share=0.3)


def test_detector_like_jitter_has_the_asked_spread_and_outliers() -> None:
    config = AugmentationConfig(keypoint_noise_sigma=0.03, keypoint_outlier_probability=0.1)
    points = torch.zeros(4000, 17, 2)
    noisy = jitter_joints(points, 128, config, torch.Generator().manual_seed(0))
    distance = noisy.norm(dim=-1)
    outliers = (distance > 5 * 0.03 * 128).float().mean()
    assert 0.04 < float(outliers) < 0.1  # a Gaussian alone puts ~0 beyond 5 sigma
    inliers = noisy[distance < 4 * 0.03 * 128]
    assert abs(float(inliers.std()) / 128 - 0.03) < 0.003


def test_train_config_builds_the_mix_and_checks_it() -> None:
    config = TrainConfig(roll_probability=0.4, steep_view_probability=0.15, archetype_share=0.3,
                         keypoint_noise_sigma=0.035)  # fmt: skip
    assert config.data_config().orientation.roll_probability == 0.4
    assert config.data_config().augmentation.keypoint_noise_sigma == 0.035
    assert config.pose_mix().archetype_share == 0.3
    with pytest.raises(ValueError, match="roll-probability"):
        TrainConfig(roll_probability=2).validate()
    with pytest.raises(ValueError, match="add up"):
        TrainConfig(archetype_share=0.7, limb_mix_share=0.5).validate()
    assert config.data_config().orientation.max_roll_deg == 180.0  # any roll unless limited
    limited = TrainConfig(roll_probability=1.0, max_roll_deg=45.0)
    assert limited.validate().data_config().orientation.max_roll_deg == 45.0
    with pytest.raises(ValueError, match="max-roll-deg"):
        TrainConfig(max_roll_deg=200.0).validate()
