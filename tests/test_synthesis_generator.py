"""The synthetic data generator end to end at a small image size."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

from hkpd.camera_conventions import perspective_project
from hkpd.poses import ProceduralPosePrior
from hkpd.synthesis.augmentations import AugmentationConfig
from hkpd.synthesis.generator import (
    SyntheticBatches,
    SyntheticDataConfig,
    SyntheticDataGenerator,
    fixed_test_set,
)
from hkpd.synthesis.preview import preview_grid

SIZE = 64


@pytest.fixture(scope="module")
def generator() -> SyntheticDataGenerator:
    return SyntheticDataGenerator(ProceduralPosePrior(), SyntheticDataConfig(image_size=SIZE))


@pytest.fixture(scope="module")
def clean_generator(generator) -> SyntheticDataGenerator:
    clean = SyntheticDataGenerator(
        ProceduralPosePrior(),
        SyntheticDataConfig(image_size=SIZE, augmentation=AugmentationConfig.disabled()),
        body=generator.body,
    )
    return clean


def test_batch_fields_and_shapes(generator) -> None:
    rendered = generator.generate(6, seed=1)
    batch = rendered.batch
    assert batch.proxy.shape == (6, 18, SIZE, SIZE) and batch.proxy.dtype == torch.float32
    assert batch.body_pose.shape == (6, 23, 3, 3)
    assert batch.global_orient.shape == (6, 3, 3)
    assert batch.betas.shape == (6, 10)
    assert batch.keypoints2d.shape == (6, 17, 2)
    assert batch.visible.shape == (6, 17) and batch.visible.dtype == torch.bool
    assert batch.joints3d.shape == (6, 24, 3)
    assert rendered.images.shape == (6, SIZE, SIZE, 3) and rendered.images.dtype == np.uint8
    eye = torch.eye(3).expand(6, 3, 3)
    torch.testing.assert_close(batch.global_orient @ batch.global_orient.mT, eye, atol=1e-5,
                               rtol=0)  # fmt: skip
    assert float(batch.proxy[:, 0].sum()) > 0  # there are edges


def test_same_seed_same_batch_other_seed_differs(generator) -> None:
    first = generator.generate(3, seed=5).batch
    again = generator.generate(3, seed=5).batch
    other = generator.generate(3, seed=6).batch
    torch.testing.assert_close(first.proxy, again.proxy)
    torch.testing.assert_close(first.keypoints2d, again.keypoints2d)
    assert not torch.equal(first.proxy, other.proxy)


def test_keypoints_are_the_projection_of_the_3d_body(clean_generator) -> None:
    """Without augmentation the whole body is in frame, its keypoints are where the camera puts
    its 3D joints after the crop, and the crop box keeps them inside the image."""
    batch = clean_generator.generate(8, seed=2).batch
    keypoints = batch.keypoints2d
    assert bool(((keypoints > -1) & (keypoints < SIZE)).all())
    body = clean_generator.body
    posed = body(batch.betas, batch.body_pose, batch.global_orient)
    keypoints3d = posed.keypoints - posed.joints[:, :1] + batch.translation[:, None]
    # Depth order is preserved by the crop's shear: projection with the crop focal length
    # differs from the stored keypoints only by a per-image 2D shift.
    projected = perspective_project(keypoints3d, batch.focal_px[:, None], SIZE)
    offset = keypoints - projected
    torch.testing.assert_close(offset, offset[:, :1].expand_as(offset), atol=1e-3, rtol=0)
    torch.testing.assert_close(batch.joints3d[:, 0], batch.translation)


def test_visible_joints_in_the_heatmaps_without_augmentation(clean_generator) -> None:
    rendered = clean_generator.generate(8, seed=3)
    batch = rendered.batch
    assert bool(torch.equal(rendered.input_present, batch.visible))
    assert float(batch.visible.float().mean()) > 0.6  # most joints of a clean render are seen
    peaks = batch.proxy[:, 1:].flatten(2).amax(-1)
    assert bool((peaks[batch.visible] > 0.5).all())
    assert bool((peaks[~batch.visible] == 0).all())


def test_stream_and_fixed_test_set_are_reproducible(generator) -> None:
    stream = iter(SyntheticBatches(generator, batch_size=2, seed=9))
    first, second = next(stream), next(stream)
    resumed = next(iter(SyntheticBatches(generator, batch_size=2, seed=9, start=1)))
    torch.testing.assert_close(second.proxy, resumed.proxy)
    assert not torch.equal(first.proxy, second.proxy)
    test_a = fixed_test_set(generator, count=5, seed=1, batch_size=2)
    test_b = fixed_test_set(generator, count=5, seed=1, batch_size=2)
    assert [b.batch_size for b in test_a] == [2, 2, 1]
    for a, b in zip(test_a, test_b, strict=True):
        torch.testing.assert_close(a.proxy, b.proxy)


def test_preview_grid_picture(generator) -> None:
    rendered = generator.generate(5, seed=4)
    picture = preview_grid(rendered, columns=2)
    assert picture.dtype == np.uint8
    assert picture.shape == (3 * (SIZE + 4), 2 * (4 * SIZE + 4), 3)


def test_worker_processes_give_the_same_stream(generator) -> None:
    from hkpd.synthesis.parallel import GeneratorSpec, ParallelBatches

    spec = GeneratorSpec(config=SyntheticDataConfig(image_size=SIZE))
    with ParallelBatches(spec, batch_size=2, seed=9, start=1, workers=2) as parallel:
        from_workers = [next(parallel) for _ in range(3)]
    in_process = iter(SyntheticBatches(generator, batch_size=2, seed=9, start=1))
    for batch in from_workers:
        torch.testing.assert_close(batch.proxy, next(in_process).proxy)


def test_packed_batch_unpacks_to_the_generated_batch(generator) -> None:
    packed = generator.generate_packed(3, seed=11)
    assert packed.image_planes.dtype == torch.uint8
    assert packed.image_planes.shape == (3, 1, SIZE, SIZE)
    assert set(packed.image_planes.unique().tolist()) <= {0, 255}
    unpacked = packed.unpack()
    direct = generator.generate(3, seed=11).batch
    for name in ("proxy", "body_pose", "betas", "keypoints2d", "visible", "joints3d"):
        torch.testing.assert_close(getattr(unpacked, name), getattr(direct, name))


def test_limb_boxes_hide_their_keypoints(generator) -> None:
    """With a limb box on every image, keypoints inside the painted box are never visible, and
    the box's limb has fewer pixels left in the picture than in the clean render."""
    limb_only = replace(
        AugmentationConfig.disabled(), limb_occlusion_probability=1.0, limb_box_margin_px=6.0
    )
    boxed = SyntheticDataGenerator(
        ProceduralPosePrior(),
        SyntheticDataConfig(image_size=SIZE, augmentation=limb_only),
        body=generator.body,
    )
    rendered = boxed.generate(8, seed=5)
    clean = SyntheticDataGenerator(
        ProceduralPosePrior(),
        SyntheticDataConfig(image_size=SIZE, augmentation=AugmentationConfig.disabled()),
        body=generator.body,
    ).generate(8, seed=5)
    changed = torch.from_numpy((rendered.images != clean.images).any(-1))  # the painted boxes
    assert changed.flatten(1).any(1).float().mean() >= 0.75
    pixel = rendered.batch.keypoints2d.round().long().clamp(0, SIZE - 1)
    rows, cols = pixel[..., 1], pixel[..., 0]
    under_box = changed[torch.arange(8)[:, None], rows, cols]
    assert under_box.any()
    assert not (rendered.batch.visible & under_box).any()
    assert (clean.batch.visible & under_box).any()  # they were visible before the box


def test_fixed_betas_change_only_the_shape(generator) -> None:
    drawn = generator.generate_packed(3, seed=11)
    betas = torch.linspace(-2, 2, 30).reshape(3, 10)
    fixed = generator.generate_packed(3, seed=11, betas=betas)
    torch.testing.assert_close(fixed.betas, betas)
    assert not torch.equal(fixed.betas, drawn.betas)
    # Every other draw is the seed's: same poses, orientations and camera distances.
    torch.testing.assert_close(fixed.body_pose, drawn.body_pose)
    torch.testing.assert_close(fixed.global_orient, drawn.global_orient)
    torch.testing.assert_close(fixed.translation, drawn.translation)
    assert not torch.equal(fixed.joints3d, drawn.joints3d)  # another body shape
    # Several views of one body: the same betas under different seeds.
    one_body = betas[:1].expand(3, 10)
    views = [generator.generate_packed(3, seed, one_body) for seed in (1, 2)]
    torch.testing.assert_close(views[0].betas, views[1].betas)
    assert not torch.equal(views[0].body_pose, views[1].body_pose)
    with pytest.raises(ValueError, match=r"betas must have shape \(3, 10\) for a batch of 3"):
        generator.generate(3, seed=11, betas=torch.zeros(2, 10))
    with pytest.raises(ValueError, match="finite"):
        generator.generate(3, seed=11, betas=torch.full((3, 10), float("nan")))


def test_silhouette_and_rgb_proxies_share_the_edge_proxys_examples(generator) -> None:
    """The ablation's proxies: same bodies, keypoints and heatmaps for one seed; the image part
    is the rendered RGB crop, or the body's silhouette without what occluders hide."""
    edges = generator.generate(4, seed=21)
    made = {}
    for kind in ("silhouette", "rgb"):
        other = SyntheticDataGenerator(
            ProceduralPosePrior(),
            SyntheticDataConfig(image_size=SIZE, image_proxy=kind),
            body=generator.body,
        )
        made[kind] = other.generate(4, seed=21)
        torch.testing.assert_close(made[kind].batch.body_pose, edges.batch.body_pose)
        torch.testing.assert_close(made[kind].batch.proxy[:, -17:], edges.batch.proxy[:, 1:])
    rgb = made["rgb"]
    assert rgb.batch.proxy.shape == (4, 20, SIZE, SIZE)
    np.testing.assert_allclose(
        rgb.batch.proxy[:, :3].permute(0, 2, 3, 1).numpy() * 255, rgb.images, atol=1e-3
    )
    silhouette = made["silhouette"].batch.proxy[:, 0]
    assert set(silhouette.unique().tolist()) == {0.0, 1.0}
    body = (made["silhouette"].part_map >= 0).cpu()
    assert not bool((silhouette.bool() & ~body).any())  # never outside the body
    # The visible keypoints (loss targets) lie on the silhouette or next to it.
    batch = made["silhouette"].batch
    grown = torch.nn.functional.max_pool2d(silhouette[:, None], 5, 1, 2)[:, 0]
    pixel = batch.keypoints2d.round().long().clamp(0, SIZE - 1)
    on_body = grown[torch.arange(4)[:, None], pixel[..., 1], pixel[..., 0]] > 0
    assert float(on_body[batch.visible].float().mean()) > 0.9
