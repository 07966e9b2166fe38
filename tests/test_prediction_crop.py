"""CropTransform: exact photo <-> crop maps, box placement, and resampling (borders, aliasing)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from hkpd.camera_conventions import CROP_SIZE, pixels_to_ndc
from hkpd.prediction import CropTransform, load_image
from hkpd.proxy import CROP_MARGIN, square_box_around_keypoints


def test_maps_are_exact_inverses_for_numpy_and_torch() -> None:
    rng = np.random.default_rng(0)
    for _ in range(20):
        crop = CropTransform(tuple(rng.uniform(-500, 3000, 2)), float(rng.uniform(5, 4000)))
        points = rng.uniform(-1000, 5000, (3, 17, 2))
        there = crop.image_to_crop(points)
        np.testing.assert_allclose(crop.crop_to_image(there), points, rtol=0, atol=1e-9)
        np.testing.assert_allclose(
            crop.image_to_crop(crop.crop_to_image(points)), points, rtol=0, atol=1e-9
        )
        tensor = torch.tensor(points)
        back = crop.crop_to_image(crop.image_to_crop(tensor))
        assert isinstance(back, torch.Tensor) and back.dtype == torch.float64
        torch.testing.assert_close(back, tensor, rtol=0, atol=1e-9)
    single = torch.tensor([100.0, 200.0], dtype=torch.float32)
    assert crop.image_to_crop(single).dtype == torch.float32
    with pytest.raises(ValueError, match=r"\(\.\.\., 2\)"):
        crop.image_to_crop(np.zeros((4, 3)))


def test_box_edges_land_on_crop_edges_and_ndc_matches_the_camera_convention() -> None:
    crop = CropTransform((400.0, 300.0), 500.0)
    x0, y0, x1, y1 = crop.box
    assert (x0, y0, x1, y1) == (150.0, 50.0, 650.0, 550.0)
    edges = crop.image_to_crop(np.array([[x0, y0], [x1, y1], [400.0, 300.0]]))
    np.testing.assert_allclose(edges, [[-0.5, -0.5], [255.5, 255.5], [127.5, 127.5]])
    image_points = torch.tensor([[123.0, 456.0], [650.0, 50.0]], dtype=torch.float64)
    ndc = pixels_to_ndc(crop.image_to_crop(image_points), CROP_SIZE)
    expected = (image_points - torch.tensor([400.0, 300.0], dtype=torch.float64)) * 2 / 500.0
    torch.testing.assert_close(ndc, expected)
    matrix = crop.affine_matrix()
    np.testing.assert_allclose(matrix @ np.array([x1, y1, 1.0]), [255.5, 255.5])


def test_identity_crop_reproduces_the_image() -> None:
    rng = np.random.default_rng(1)
    image = rng.integers(0, 256, (256, 256, 3), dtype=np.uint8)
    crop = CropTransform((127.5, 127.5), 256.0)
    np.testing.assert_array_equal(crop.crop_image(image), image)


def test_crop_beyond_the_photo_is_black_outside_and_exact_inside() -> None:
    rng = np.random.default_rng(2)
    image = rng.integers(1, 256, (300, 400, 3), dtype=np.uint8)  # no zeros inside the photo
    # A 256-px box whose top-left crop pixel sits on photo pixel (-100, 150): integer shift.
    crop = CropTransform((-100 + 127.5, 150 + 127.5), 256.0)
    out = crop.crop_image(image)
    assert out.shape == (256, 256, 3) and out.dtype == np.uint8
    np.testing.assert_array_equal(out[:, :100], 0)  # left of the photo
    np.testing.assert_array_equal(out[150:], 0)  # below the photo
    np.testing.assert_array_equal(out[:150, 100:], image[150:300, 0:156])
    # A box that misses the photo entirely is all border.
    assert not CropTransform((5000.0, 5000.0), 800.0).crop_image(image).any()


def test_large_box_is_antialiased_and_keeps_geometry() -> None:
    size = 2560  # box 10x the crop: plain bilinear sampling would alias a 1-px checkerboard
    u, v = np.meshgrid(np.arange(size), np.arange(size))
    image = (((u + v) % 2) * 255).astype(np.uint8)[:, :, None].repeat(3, 2)
    image[1000:1100, 1500:1700] = (255, 0, 0)  # a red patch, centroid (1599.5, 1049.5)
    crop = CropTransform(((size - 1) / 2, (size - 1) / 2), float(size))
    out = crop.crop_image(image).astype(float)
    background = out[:80, :80, 1]
    assert abs(background.mean() - 127.5) < 3 and background.std() < 3
    red = (out[:, :, 0] > 200) & (out[:, :, 1] < 60)
    ys, xs = np.nonzero(red)
    expected = crop.image_to_crop(np.array([1599.5, 1049.5]))
    np.testing.assert_allclose([xs.mean(), ys.mean()], expected, atol=0.6)


def test_crop_of_a_downscaled_working_copy_matches_the_crop_of_the_original() -> None:
    rng = np.random.default_rng(3)
    small = rng.integers(0, 256, (60, 80, 3), dtype=np.uint8)
    original = np.kron(small, np.ones((50, 50, 1), np.uint8))  # 4000 x 3000, smooth blocks
    loaded = load_image(original, max_side=1000)
    assert loaded.scale == (0.25, 0.25)
    crop = CropTransform((2100.0, 1400.0), 1800.0)
    from_original = crop.crop_image(original).astype(int)
    from_working = crop.crop_image(loaded.pixels, loaded.scale).astype(int)
    np.testing.assert_array_equal(crop.crop_image(loaded), from_working)
    # Block edges are where the two resamplings may differ; everywhere else they agree.
    assert np.median(np.abs(from_original - from_working)) <= 1
    assert np.mean(np.abs(from_original - from_working)) < 6


def test_from_keypoints_uses_the_training_box_rule() -> None:
    rng = np.random.default_rng(4)
    keypoints = rng.uniform(100, 600, (17, 2))
    confidences = rng.uniform(0, 1, 17)
    crop = CropTransform.from_keypoints(keypoints, confidences, min_confidence=0.5)
    kept = confidences >= 0.5
    centre, side = square_box_around_keypoints(
        torch.from_numpy(keypoints)[None], torch.from_numpy(kept)[None], CROP_MARGIN
    )
    np.testing.assert_allclose(crop.centre, centre[0].numpy())
    assert crop.side == pytest.approx(float(side[0]))
    low, high = keypoints[kept].min(0), keypoints[kept].max(0)
    assert crop.side == pytest.approx(CROP_MARGIN * (high - low).max())
    # By default every keypoint counts, whatever its confidence.
    everything = CropTransform.from_keypoints(keypoints, np.zeros(17))
    assert everything.side == pytest.approx(CROP_MARGIN * np.ptp(keypoints, 0).max())


def test_from_keypoints_clamps_out_of_photo_points_when_given_the_photo_size() -> None:
    keypoints = np.array([[100.0, 50.0], [140.0, 120.0], [120.0, 900.0]])  # an ankle far below
    unclamped = CropTransform.from_keypoints(keypoints)
    clamped = CropTransform.from_keypoints(keypoints, image_size=(300, 400))
    assert unclamped.side == pytest.approx(1.2 * 850)
    assert clamped.side == pytest.approx(1.2 * (399.5 - 50))
    assert clamped.centre[1] == pytest.approx((50 + 399.5) / 2)


def test_from_keypoints_and_from_bbox_errors() -> None:
    keypoints = np.array([[10.0, 10.0], [200.0, 300.0], [50.0, 60.0]])
    with pytest.raises(ValueError, match="at least two"):
        CropTransform.from_keypoints(keypoints, np.array([0.9, 0.1, 0.1]), min_confidence=0.5)
    with pytest.raises(ValueError, match=r"\(3,\)"):
        CropTransform.from_keypoints(keypoints, np.ones(4))
    with pytest.raises(ValueError, match="pixels wide"):
        CropTransform.from_keypoints(np.array([[10.0, 10.0], [11.0, 11.0]]))
    with pytest.raises(ValueError, match="x1 > x0"):
        CropTransform.from_bbox((10, 10, 5, 20))
    with pytest.raises(ValueError, match="positive"):
        CropTransform((0.0, 0.0), 0.0)
    crop = CropTransform.from_bbox((100, 200, 300, 600))
    assert crop.centre == (200.0, 400.0) and crop.side == pytest.approx(480.0)
    assert CropTransform.from_bbox((100, 200, 300, 600), margin=1.0).side == 400.0


@pytest.mark.parametrize("view", ["front", "side"])
def test_keypoint_box_holds_the_whole_standing_body(view: str) -> None:
    """COCO keypoints stop at the eyes and ankles; the margin must still fit head and feet."""
    from hkpd.body import BodyModel

    body = BodyModel()
    angle = 0.0 if view == "front" else np.pi / 2
    turn = torch.tensor(
        [[np.cos(angle), 0, np.sin(angle)], [0, 1, 0], [-np.sin(angle), 0, np.cos(angle)]],
        dtype=torch.float32,
    )
    # Arms down: rotate the shoulders (SMPL joints 16, 17 -> body-pose rows 15, 16) by ∓70°.
    pose = torch.eye(3).repeat(1, 23, 1, 1)
    for row, sign in ((15, -1.0), (16, 1.0)):
        a = sign * np.deg2rad(70)
        pose[0, row] = torch.tensor(
            [[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]]
        )
    for betas in (torch.zeros(1, 10), torch.full((1, 10), 2.0), torch.full((1, 10), -2.0)):
        out = body(betas, pose, turn[None])
        # Orthographic view, 500 px per metre, y down.
        to_pixels = np.array([500.0, -500.0])
        vertices = out.vertices[0, :, :2].numpy() * to_pixels + 1000
        keypoints = out.keypoints[0, :, :2].numpy() * to_pixels + 1000
        crop = CropTransform.from_keypoints(keypoints)
        x0, y0, x1, y1 = crop.box
        assert vertices[:, 0].min() > x0 and vertices[:, 0].max() < x1
        assert vertices[:, 1].min() > y0 and vertices[:, 1].max() < y1
