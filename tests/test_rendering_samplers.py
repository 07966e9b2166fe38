"""Lighting, camera, clothing and background samplers, and shading (CPU, fast)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
import torch

from hkpd.body import BodyModel
from hkpd.rendering import (
    BackgroundSource,
    ClothingTextureSampler,
    Lighting,
    sample_cameras,
    sample_lighting,
)
from hkpd.rendering.clothing import HAND_PARTS, HEAD_PART
from hkpd.rendering.lighting import MAX_LIGHT_ANGLE_DEG, shade


@pytest.fixture(scope="module")
def body() -> BodyModel:
    return BodyModel()


@pytest.fixture(scope="module")
def clothing(body: BodyModel) -> ClothingTextureSampler:
    return ClothingTextureSampler(body.v_template, body.faces, body.part_labels)


def test_lighting_ranges_follow_the_paper():
    lighting = sample_lighting(4000, torch.Generator().manual_seed(0))
    for name, (low, high) in {
        "ambient": (0.4, 0.8),
        "diffuse": (0.4, 0.8),
        "specular": (0.0, 0.5),
    }.items():
        values = getattr(lighting, name)
        assert values.shape == (4000,)
        assert values.min() >= low and values.max() <= high
        # Spread over the whole range, not a constant.
        assert values.min() < low + 0.02 and values.max() > high - 0.02
    assert torch.allclose(lighting.direction.norm(dim=1), torch.ones(4000), atol=1e-5)
    angle = torch.rad2deg(torch.acos(-lighting.direction[:, 2]))
    assert angle.max() <= MAX_LIGHT_ANGLE_DEG + 1e-3
    assert angle.max() > MAX_LIGHT_ANGLE_DEG - 5
    assert (lighting.colour >= 0.8).all() and (lighting.colour <= 1.0).all()


def test_shading_is_brighter_facing_the_light_and_adds_highlights():
    lighting = Lighting(
        ambient=torch.tensor([0.4]),
        diffuse=torch.tensor([0.6]),
        specular=torch.tensor([0.5]),
        direction=torch.tensor([[0.0, 0.0, -1.0]]),
        colour=torch.ones(1, 3),
        shininess=torch.tensor([20.0]),
    )
    angles = torch.tensor([0.0, 0.5, 1.0, 2.0])  # tilt of the normal away from the light
    normals = torch.stack((angles.sin(), torch.zeros(4), -angles.cos()))[None]
    view = torch.tensor([0.0, 0.0, -1.0])[None, :, None].expand(1, 3, 4)
    albedo = torch.full((1, 3, 4), 0.5)
    colour = shade(albedo, normals, view, lighting)[0, 0]
    assert (colour[:-1].diff() < 0).all()
    # Facing away: ambient only. Facing the light: ambient + diffuse + full highlight.
    assert torch.isclose(colour[3], torch.tensor(0.5 * 0.4))
    assert torch.isclose(colour[0], torch.tensor(min(1.0, 0.5 * (0.4 + 0.6) + 0.5)))


def test_cameras_follow_the_paper_in_opencv_axes():
    translation, focal = sample_cameras(20000, torch.Generator().manual_seed(0))
    assert translation.shape == (20000, 3) and focal.shape == (20000,)
    assert torch.all(focal == 300.0)
    mean = translation.mean(dim=0)
    assert torch.allclose(mean, torch.tensor([0.0, 0.2, 2.5]), atol=0.01)
    assert torch.allclose(translation[:, :2].std(dim=0), torch.tensor([0.05, 0.05]), rtol=0.05)
    assert translation[:, 2].min() >= 2.25 and translation[:, 2].max() <= 2.75


def test_clothing_is_deterministic_and_in_range(clothing: ClothingTextureSampler):
    first = clothing.sample(6, torch.Generator().manual_seed(5))
    second = clothing.sample(6, torch.Generator().manual_seed(5))
    other = clothing.sample(6, torch.Generator().manual_seed(6))
    assert first.shape == (6, clothing.num_faces, 3) and first.dtype == torch.float32
    assert torch.equal(first, second)
    assert not torch.equal(first, other)
    assert first.min() >= 0.0 and first.max() <= 1.0


def test_clothing_has_garment_regions(body: BodyModel):
    no_grey = ClothingTextureSampler(body.v_template, body.faces, body.part_labels, 0.0)
    albedo = no_grey.sample(40, torch.Generator().manual_seed(1))
    face_part = body.part_labels[body.faces[:, 0]]
    hands = torch.isin(face_part, torch.tensor(HAND_PARTS))
    torso = face_part == 3
    # Hands are bare skin: one colour per body; the torso is clothed: a different colour.
    hand_colours = albedo[:, hands]
    assert torch.allclose(hand_colours, hand_colours[:, :1].expand_as(hand_colours))
    torso_mean = albedo[:, torso].mean(dim=1)
    assert ((torso_mean - hand_colours[:, 0]).abs().sum(dim=1) > 0.05).float().mean() > 0.8
    # Outfits differ: several distinct colours per body, and patterned garments exist.
    distinct = [len(torch.unique(a, dim=0)) for a in albedo]
    assert min(distinct) >= 3 and max(distinct) >= 5
    head = face_part == HEAD_PART
    assert any(len(torch.unique(a[head], dim=0)) == 2 for a in albedo)  # skin + hair


def test_grey_fraction(body: BodyModel):
    sampler = ClothingTextureSampler(body.v_template, body.faces, body.part_labels, 0.1)
    generator = torch.Generator().manual_seed(2)
    grey = 0
    total = 0
    for _ in range(3):
        albedo = sampler.sample(200, generator)
        uniform = (albedo == albedo[:, :1, :1]).flatten(1).all(dim=1)
        grey += int(uniform.sum())
        total += 200
    assert abs(grey / total - 0.1) < 0.04  # binomial std 0.012 for 600 bodies
    with pytest.raises(ValueError, match="grey_fraction"):
        ClothingTextureSampler(body.v_template, body.faces, body.part_labels, 1.5)


def test_clothing_rejects_non_smpl_labels(body: BodyModel):
    with pytest.raises(ValueError, match="SMPL"):
        ClothingTextureSampler(body.v_template, body.faces, torch.zeros_like(body.part_labels))


def test_procedural_backgrounds():
    source = BackgroundSource()
    first = source.sample(3, torch.Generator().manual_seed(0), 64)
    second = source.sample(3, torch.Generator().manual_seed(0), 64)
    assert first.shape == (3, 3, 64, 64) and first.dtype == torch.float32
    assert torch.equal(first, second)
    assert first.min() >= 0.0 and first.max() <= 1.0
    assert not torch.equal(first[0], first[1])
    # Clutter: a good share of pixels sit on edges.
    grey = (first[0].mean(dim=0).numpy() * 255).astype(np.uint8)
    assert (cv2.Canny(grey, 30, 60) > 0).mean() > 0.01


def test_pooled_procedural_backgrounds_are_cheap_crops():
    source = BackgroundSource(pool_size=8, refresh_fraction=0.25)
    generator = torch.Generator().manual_seed(0)
    first = source.sample(16, generator, 48)
    assert first.shape == (16, 3, 48, 48)
    assert first.min() >= 0.0 and first.max() <= 1.0
    assert len(source._pool) == 8 and source._pool[0].shape == (60, 60, 3)
    pool_before = [p.copy() for p in source._pool]
    second = source.sample(16, generator, 48)
    replaced = sum(not np.array_equal(a, b) for a, b in zip(pool_before, source._pool, strict=True))
    assert 1 <= replaced <= 4  # 25% of 16 drawn anew
    assert not torch.equal(first, second)
    again = BackgroundSource(pool_size=8).sample(16, torch.Generator().manual_seed(0), 48)
    assert torch.equal(again, first)
    with pytest.raises(ValueError, match="pool_size"):
        BackgroundSource(pool_size=-1)


def write_image(path: Path, rgb: tuple[int, int, int], size: tuple[int, int]) -> None:
    image = np.zeros((*size, 3), dtype=np.uint8)
    image[:] = rgb[::-1]  # OpenCV writes BGR
    path.parent.mkdir(parents=True, exist_ok=True)
    assert cv2.imwrite(str(path), image)


def test_folder_backgrounds_crop_the_user_images(tmp_path: Path):
    write_image(tmp_path / "red.png", (255, 0, 0), (90, 120))
    write_image(tmp_path / "nested" / "deeper" / "blue.JPG", (0, 0, 255), (300, 200))
    (tmp_path / "notes.txt").write_text("not an image")
    source = BackgroundSource(tmp_path)
    assert len(source.files) == 2
    images = source.sample(24, torch.Generator().manual_seed(0), 32)
    assert images.shape == (24, 3, 32, 32)
    means = images.mean(dim=(2, 3))
    red = (means[:, 0] > 0.95) & (means[:, 2] < 0.05)
    blue = (means[:, 2] > 0.95) & (means[:, 0] < 0.05)
    assert torch.all(red | blue) and red.any() and blue.any()


def test_folder_errors_are_clear(tmp_path: Path):
    with pytest.raises(ValueError, match="contains no images"):
        BackgroundSource(tmp_path)
    with pytest.raises(FileNotFoundError, match="not a directory"):
        BackgroundSource(tmp_path / "missing")


def test_lighting_device_move_keeps_values():
    lighting = sample_lighting(3, torch.Generator().manual_seed(0))
    moved = lighting.to("cpu")
    assert all(
        torch.equal(getattr(lighting, name), getattr(moved, name))
        for name in ("ambient", "diffuse", "specular", "direction", "colour", "shininess")
    )
    assert lighting.batch_size == 3


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA")
def test_samplers_take_a_cpu_generator_for_cuda_output(clothing: ClothingTextureSampler):
    generator = torch.Generator().manual_seed(0)
    translation, focal = sample_cameras(4, generator, "cuda")
    lighting = sample_lighting(4, generator, "cuda")
    albedo = clothing.sample(4, generator, "cuda")
    backgrounds = BackgroundSource().sample(4, generator, 32, "cuda")
    assert translation.is_cuda and focal.is_cuda and lighting.ambient.is_cuda
    assert albedo.is_cuda and backgrounds.is_cuda
    # Same draws as on the CPU: the generator's device decides the random numbers.
    on_cpu = clothing.sample(2, torch.Generator().manual_seed(3), "cpu")
    on_gpu = clothing.sample(2, torch.Generator().manual_seed(3), "cuda")
    assert torch.equal(on_gpu.cpu(), on_cpu)
