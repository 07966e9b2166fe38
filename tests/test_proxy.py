"""The proxy representation: edges, heatmaps, confidence threshold, crop box."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from hkpd.proxy import (
    CONFIDENCE_THRESHOLD,
    IMAGE_PROXIES,
    assemble_proxy,
    build_proxy,
    build_proxy_batch,
    canny_edges,
    heatmap_std,
    image_planes_batch,
    joint_heatmaps,
    proxy_channels,
    proxy_image_planes,
    square_box_around_keypoints,
)


def test_heatmap_peaks_at_the_joint_with_the_documented_std() -> None:
    keypoints = torch.tensor([[[100.0, 40.0]]])
    maps = joint_heatmaps(keypoints, torch.ones(1, 1, dtype=torch.bool), 256)
    assert maps.shape == (1, 1, 256, 256)
    row, col = divmod(int(maps[0, 0].argmax()), 256)
    assert (col, row) == (100, 40)
    assert float(maps[0, 0, 40, 100]) == pytest.approx(1.0)
    std = heatmap_std(256)
    assert std == 4.0
    assert float(maps[0, 0, 40, 104]) == pytest.approx(np.exp(-0.5), rel=1e-5)


def test_subpixel_keypoint_and_scaled_std() -> None:
    maps = joint_heatmaps(torch.tensor([[[10.5, 20.0]]]), torch.ones(1, 1, dtype=torch.bool), 64)
    assert float(maps[0, 0, 20, 10]) == pytest.approx(float(maps[0, 0, 20, 11]))
    assert heatmap_std(64) == 1.0


def test_low_confidence_joints_are_dropped() -> None:
    image = np.zeros((256, 256, 3), np.uint8)
    keypoints = np.full((17, 2), 128.0)
    confidences = np.full(17, 0.9)
    confidences[3] = CONFIDENCE_THRESHOLD - 0.01
    confidences[4] = CONFIDENCE_THRESHOLD
    proxy = build_proxy(image, keypoints, confidences)
    assert proxy.shape == (18, 256, 256)
    assert float(proxy[1 + 3].max()) == 0.0
    assert float(proxy[1 + 4].max()) == pytest.approx(1.0)
    assert float(proxy[0].max()) == 0.0  # a blank image has no edges


def test_edges_trace_a_square_outline() -> None:
    image = np.zeros((64, 64, 3), np.uint8)
    image[16:48, 16:48] = 255
    edges = canny_edges(image)
    assert set(np.unique(edges)) == {0.0, 1.0}
    assert edges[32, 14:18].max() == 1.0 and edges[32, 30:34].max() == 0.0


def test_edges_reject_wrong_input() -> None:
    with pytest.raises(ValueError, match="uint8"):
        canny_edges(np.zeros((8, 8, 3), np.float32))


def test_batch_matches_single_and_validates_shapes() -> None:
    generator = np.random.default_rng(0)
    images = generator.integers(0, 255, (2, 64, 64, 3), dtype=np.uint8)
    keypoints = torch.rand(2, 17, 2) * 64
    present = torch.rand(2, 17) > 0.3
    batch = build_proxy_batch(images, keypoints, present)
    single = build_proxy(images[1], keypoints[1], present[1].float())
    torch.testing.assert_close(batch[1], single)
    with pytest.raises(ValueError, match="keypoints"):
        build_proxy_batch(images, keypoints[:, :5], present)


def test_square_box_around_keypoints() -> None:
    keypoints = torch.tensor([[[10.0, 20.0], [30.0, 100.0], [500.0, 500.0]]])
    present = torch.tensor([[True, True, False]])
    centre, side = square_box_around_keypoints(keypoints, present, margin=1.5)
    torch.testing.assert_close(centre, torch.tensor([[20.0, 60.0]]))
    torch.testing.assert_close(side, torch.tensor([120.0]))
    with pytest.raises(ValueError, match="two keypoints"):
        square_box_around_keypoints(keypoints, torch.tensor([[True, False, False]]))


def test_image_proxies_layout_and_round_trip() -> None:
    rng = np.random.default_rng(3)
    images = rng.integers(0, 255, (2, 32, 32, 3), dtype=np.uint8)
    silhouettes = rng.random((2, 32, 32)) > 0.5
    keypoints, present = torch.rand(2, 17, 2) * 32, torch.ones(2, 17, dtype=torch.bool)
    for kind, channels in IMAGE_PROXIES.items():
        planes = image_planes_batch(images, kind, silhouettes)
        assert planes.shape == (2, channels, 32, 32) and planes.dtype == torch.uint8
        proxy = assemble_proxy(planes, keypoints, present)
        assert proxy.shape == (2, proxy_channels(kind), 32, 32)
        torch.testing.assert_close(proxy_image_planes(proxy), planes)
        torch.testing.assert_close(
            proxy, build_proxy_batch(images, keypoints, present, None, kind, silhouettes)
        )
    rgb = build_proxy_batch(images, keypoints, present, image_proxy="rgb")
    np.testing.assert_allclose(rgb[:, :3].permute(0, 2, 3, 1).numpy(), images / 255, atol=1e-6)
    silhouette = build_proxy(images[0], keypoints[0], np.ones(17), "silhouette", silhouettes[0])
    np.testing.assert_array_equal(silhouette[0].numpy() == 1.0, silhouettes[0])


def test_image_proxy_errors_say_what_is_missing() -> None:
    images = np.zeros((1, 16, 16, 3), np.uint8)
    with pytest.raises(ValueError, match="silhouette proxy needs person masks"):
        image_planes_batch(images, "silhouette")
    with pytest.raises(ValueError, match=r"silhouettes must be \(1, 16, 16\)"):
        image_planes_batch(images, "silhouette", np.ones((1, 8, 8), bool))
    with pytest.raises(ValueError, match="unknown image proxy 'depth'"):
        image_planes_batch(images, "depth")
    with pytest.raises(ValueError, match="uint8"):
        assemble_proxy(torch.zeros(1, 1, 16, 16), torch.zeros(1, 17, 2), torch.ones(1, 17).bool())
